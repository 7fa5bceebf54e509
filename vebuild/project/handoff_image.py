"""A photo's image as a file handed to other software (the camera-only glTF's photo plane, an fSpy
project): the original bytes where another program shows them as vebuild does, else a copy.

vebuild's pixels are the photo *as displayed* (its EXIF orientation applied; FORMAT.md). The
original file is kept, byte for byte, where it is a JPEG or PNG with no turning orientation and no
larger than asked: every program then shows the same pixels. Otherwise (a TIFF or RAW file, an
EXIF orientation other than 1, which Blender and glTF textures ignore, or a side above ``max_px``)
the displayed pixels are written anew: JPEG (quality :data:`JPEG_QUALITY`) for a JPEG or RAW
photo, PNG for the rest, downscaled to ``max_px`` where asked. ``note`` says which, in words.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

from PIL import Image

from vebuild.errors import VebuildError

from .file import Project
from .images import decode_photo, photo_orientation, sha256_bytes

#: Quality of a JPEG copy: high, since the copy stands for the evidence's pixels.
JPEG_QUALITY = 95
MIME = {"JPEG": "image/jpeg", "PNG": "image/png"}


@dataclass(frozen=True)
class HandoffImage:
    data: bytes
    mime: str  # image/jpeg or image/png
    size: tuple[int, int]  # width, height of ``data`` (pixels)
    original: bool  # the photo's own bytes
    note: str


def handoff_image(project: Project, photo_id: str, max_px: int | None = None) -> HandoffImage:
    """The image of photo ``photo_id`` to embed (see the module's docstring)."""
    photo = project.photo(photo_id)
    where = f"$.photos[{project.data['photos'].index(photo)}].file"
    path = project.photo_path(photo)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise VebuildError(f"{project.path}: {where}: cannot read the photo {path} ({e.strerror or e}); "
                           "put it back where the project says, or run `vebuild check` to see what moved") from None
    fmt = None
    try:
        with Image.open(io.BytesIO(data)) as img:
            fmt, size, mode = img.format, img.size, img.mode
            turned = photo_orientation(img, project.path, where, str(path)) != 1
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError):
        fmt, size, mode, turned = None, (0, 0), "", True  # RAW or unreadable here: decode_photo says which
    small = max_px is None or max(size) <= max_px
    if fmt in MIME and not turned and small and mode in ("RGB", "L"):
        return HandoffImage(data, MIME[str(fmt)], size, True,
                            f"the photo's own {fmt} file, byte for byte (SHA-256 {sha256_bytes(data)})")
    pixels = Image.fromarray(decode_photo(data, path.name, project.path, where, label=str(path)))
    why = []
    if turned:
        why.append("turned upright by its EXIF orientation")
    if max_px is not None and max(pixels.size) > max_px:
        scale = max_px / max(pixels.size)
        pixels = pixels.resize((max(1, round(pixels.width * scale)), max(1, round(pixels.height * scale))),
                               Image.Resampling.LANCZOS)
        why.append(f"downscaled to {pixels.width}×{pixels.height}")
    out_fmt = "JPEG" if fmt in ("JPEG", "MPO", None) else "PNG"
    if fmt not in MIME:
        why.append(f"re-encoded from {fmt or 'a RAW file'}")
    buf = io.BytesIO()
    pixels.save(buf, out_fmt, **({"quality": JPEG_QUALITY} if out_fmt == "JPEG" else {}))
    note = (f"a {out_fmt} copy of the photo as vebuild shows it ({', '.join(why) or 're-encoded'}); the original is "
            f"{path.name}, SHA-256 {photo.get('sha256') or sha256_bytes(data)}")
    return HandoffImage(buf.getvalue(), MIME[out_fmt], pixels.size, False, note)
