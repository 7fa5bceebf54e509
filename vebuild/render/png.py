"""PNG files with provenance: every image vebuild writes (renders, screenshots, analyses' views
and maps, the report's images) goes through :func:`write_png`, atomically, with the text chunks of
:func:`provenance` (:data:`PROVENANCE_KEYS`): the SHA-256 of the project file it was made from, the
camera (named view or photo, with K, R, C, size and a photo's lens distortion), the lighting preset
and its lights, the stereo settings, the texture pages' hashes, the unit of lengths (metres, or
relative units where the project has no scale) and the software version, and no time stamp, so that
the same project and options give the same file, byte for byte.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image, PngImagePlugin

from vebuild import __version__
from vebuild.camera import ImageCamera
from vebuild.errors import VebuildError
from vebuild.project import Project
from vebuild.project.provenance import inputs_sha256, stage_hashes, stale_record
from vebuild.project.units import RELATIVE_UNITS, length_unit

#: Text keys written into every rendered PNG.
PROVENANCE_KEYS = ("Software", "vebuild:project", "vebuild:inputs_sha256", "vebuild:camera", "vebuild:lighting",
                   "vebuild:stereo", "vebuild:textures", "vebuild:options", "vebuild:lengths",
                   "vebuild:stages", "vebuild:stale")  # the last two: vebuild.project.provenance

def check_output(path: Path, suffixes: tuple[str, ...] = (".png",), project: Project | None = None) -> Path:
    """Fail early, before any work, if ``path`` cannot be written as an output file: also where
    the output policy (:mod:`vebuild.project.outputs`: never over the project's own files, only over a
    file vebuild wrote) forbids it."""
    from vebuild.project.outputs import check_file

    path = Path(path)
    check_file(project, path, suffix=suffixes[0])
    if path.is_dir():
        raise VebuildError(f"{path}: is a folder; expected a file name for the output")
    if path.suffix.lower() not in suffixes:
        raise VebuildError(f"{path}: expected an output file ending in {' or '.join(suffixes)}")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise VebuildError(f"{path}: the folder {folder} does not exist; create it first or choose another path")
    if not os.access(folder, os.W_OK):
        raise VebuildError(f"{path}: the folder {folder} cannot be written to (permission denied)")
    if path.exists() and not os.access(path, os.W_OK):
        raise VebuildError(f"{path}: the existing file cannot be overwritten (permission denied)")
    return path


def write_png(path: Path, image: NDArray[np.uint8], text: dict[str, str], compress_level: int = 6) -> None:
    """Write an RGB image with text chunks atomically (:mod:`vebuild.project.atomic`); ``compress_level``
    is zlib's (the same pixels at any: 1 writes a 1600 × 1200 render some four times faster, a
    quarter larger)."""
    from vebuild.project.atomic import write_with

    info = PngImagePlugin.PngInfo()
    for k, v in text.items():
        info.add_itxt(k, v) if not v.isascii() else info.add_text(k, v)
    try:
        write_with(path, lambda f: Image.fromarray(image, "RGB").save(f, format="PNG", pnginfo=info,
                                                                   compress_level=compress_level))
    except OSError as e:
        raise VebuildError(f"{path}: cannot write the image ({e.strerror or e})") from None


def stamp(image: NDArray[np.uint8], text: str) -> NDArray[np.uint8]:
    """The image with ``text`` in a red band across its top (how a hypothesis is labelled)."""
    from PIL import ImageDraw, ImageFont

    img = Image.fromarray(image, "RGB")
    size = max(12, img.height // 28)
    font = ImageFont.load_default(size=size)
    draw = ImageDraw.Draw(img)
    box = draw.textbbox((0, 0), text, font=font)
    pad = size // 2
    draw.rectangle((0, 0, img.width, box[3] + 2 * pad), fill=(170, 20, 20))
    draw.text((pad, pad), text, fill=(255, 255, 255), font=font)
    return np.asarray(img)


def _camera_record(cam: ImageCamera, kind: str) -> dict[str, Any]:
    """The camera of a render's provenance; a photo's lens distortion (the division model's k1,
    vebuild/camera.py) where it has one (a pinhole's record is as it always was)."""
    out: dict[str, Any] = {"kind": kind, "name": cam.id, "width": cam.width, "height": cam.height,
                           "K": np.round(cam.K, 9).tolist(), "R": np.round(cam.R, 12).tolist(),
                           "C": np.round(cam.C, 9).tolist()}
    if not cam.lens.is_pinhole:
        out["distortion"] = {"model": "division", "k1": float(np.round(cam.lens.k1, 12))}
        if cam.lens.k2 != 0.0:
            out["distortion"]["k2"] = float(np.round(cam.lens.k2, 12))
    return out


def _lighting_record(project: Project, name: str) -> dict[str, Any]:
    for rec in (project.data.get("lighting") or {}).get("presets", []):
        if rec["name"] == name:
            return rec
    return {"name": name}


def provenance(project: Project, cam: ImageCamera, kind: str, lighting: str, stereo: dict[str, Any] | None,
               page_hashes: list[str], options: dict[str, Any]) -> dict[str, str]:
    """The PNG text chunks of a render (:data:`PROVENANCE_KEYS`)."""
    def js(x: Any) -> str:
        return json.dumps(x, sort_keys=True, ensure_ascii=False)
    return {
        "Software": f"vebuild {__version__}",
        "vebuild:project": project.path.name,
        "vebuild:inputs_sha256": inputs_sha256(project.data),  # FORMAT.md "Inputs digest"
        "vebuild:camera": js(_camera_record(cam, kind)),
        "vebuild:lighting": js(_lighting_record(project, lighting)),
        "vebuild:stereo": js(stereo),
        "vebuild:textures": js(page_hashes),
        "vebuild:options": js(options),
        # The unit of the camera's C (and of every length the image shows): metres, or relative.
        "vebuild:lengths": RELATIVE_UNITS if length_unit(project.data).relative else "metres",
        # The SHA-256 of each stage's record the render used, and the stale ones with their reasons.
        "vebuild:stages": js(stage_hashes(project.data)), "vebuild:stale": js(stale_record(project.data)),
    }
