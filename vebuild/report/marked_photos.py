"""Each original photo with the operator's marks drawn over it, for the report.

The photo is decoded as every consumer decodes it (:func:`vebuild.project.images.decode_photo`:
turned by its EXIF orientation), reduced to the report's image width
(:data:`vebuild.render.sizes.IMAGE_WIDTH`), and the marks of the project drawn on it: the vanishing
segments and polylines coloured by world axis (x red, y green, z blue, each with an arrow head at
its end: the axis' positive sense), the marker observations as rings labelled with the marker's
name, the pins as crosses and the edge observations as magenta lines. Drawing is by Pillow on the
pixels, with no time in the file: the same project gives the same PNG bytes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.project import Project

#: Colours of the marks (sRGB).
AXIS_RGB = {"x": (230, 40, 40), "y": (40, 200, 40), "z": (50, 110, 255)}
MARKER_RGB = (255, 170, 0)
PIN_RGB = (255, 255, 0)
EDGE_RGB = (230, 0, 230)


def marked_photo(project: Project, index: int, width: int) -> tuple[NDArray[np.uint8], dict[str, int]]:
    """Photo ``index`` of ``$.photos`` at ``width`` pixels wide with its marks drawn; and the count
    of each kind of mark drawn."""
    from PIL import Image, ImageDraw, ImageFont

    from vebuild.project.images import decode_photo

    photo = project.data["photos"][index]
    path = project.folder / photo["file"]
    where = f"$.photos[{index}].file"
    try:
        data = path.read_bytes()
    except OSError as e:
        from vebuild.errors import ProjectError

        raise ProjectError(project.path, where, f"cannot read the photo {path} ({e.strerror or e})") from None
    pixels = decode_photo(data, path.name, project.path, where, label=str(path))
    h0, w0 = pixels.shape[:2]
    s = width / w0
    height = max(1, round(h0 * s))
    img = Image.fromarray(pixels, "RGB").resize((width, height), Image.Resampling.LANCZOS)
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default(size=max(14, width // 48))
    lw = max(1, round(width / 480))
    counts = {"segments": 0, "markers": 0, "pins": 0, "edges": 0}

    def pt(u: float, v: float) -> tuple[float, float]:
        return (u * s, v * s)

    for axis, rows in sorted((photo.get("vanishing_segments") or {}).items()):
        colour = AXIS_RGB.get(axis, (255, 255, 255))
        for row in rows:
            xy = [pt(row[k], row[k + 1]) for k in range(0, len(row) - 1, 2)]
            draw.line(xy, fill=colour, width=lw + 1)
            _arrow_head(draw, xy[-2], xy[-1], colour, 4 * lw + 4)
            counts["segments"] += 1
    for obs in (project.data.get("model") or {}).get("edge_observations", []):
        if obs["photo"] == photo["id"]:
            draw.line([pt(*q) for q in obs["points"]], fill=EDGE_RGB, width=lw)
            counts["edges"] += 1
    r = 3 * lw + 2
    for p in (project.data.get("model") or {}).get("pins", []):
        if p["photo"] == photo["id"]:
            x, y = pt(*p["uv"])
            draw.line([(x - r, y), (x + r, y)], fill=PIN_RGB, width=lw)
            draw.line([(x, y - r), (x, y + r)], fill=PIN_RGB, width=lw)
            counts["pins"] += 1
    R = 5 * lw + 3
    for name, uv in sorted((photo.get("marker_observations") or {}).items()):
        x, y = pt(*uv)
        draw.ellipse([(x - R, y - R), (x + R, y + R)], outline=MARKER_RGB, width=lw + 1)
        at = (x + R + 2, y - R - 2)
        box = draw.textbbox(at, name, font=font)
        if box[2] + 2 > width:  # by the right edge: the label goes to the ring's left
            at = (x - R - 2 - (box[2] - box[0]), at[1])
            box = draw.textbbox(at, name, font=font)
        draw.rectangle((box[0] - 2, box[1] - 2, box[2] + 2, box[3] + 2), fill=(0, 0, 0))
        draw.text(at, name, fill=MARKER_RGB, font=font)
        counts["markers"] += 1
    return np.asarray(img), counts


def _arrow_head(draw: Any, a: Sequence[float], b: Sequence[float], colour: tuple[int, int, int], size: float) -> None:
    d = np.subtract(b, a)
    n = float(np.hypot(*d))
    if n < 1e-9:
        return
    d = d / n
    side = np.array([-d[1], d[0]])
    tip = np.asarray(b, float)
    base = tip - size * d
    draw.polygon([tuple(tip), tuple(base + 0.5 * size * side), tuple(base - 0.5 * size * side)], fill=colour)
