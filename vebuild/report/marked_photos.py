"""Each original photo with the operator's marks drawn over it, for the report.

The photo is decoded as every consumer decodes it (:func:`vebuild.project.images.decode_photo`:
turned by its EXIF orientation), reduced to the report's image width
(:data:`vebuild.render.sizes.IMAGE_WIDTH`), and the marks of the project drawn on it: the vanishing
segments and polylines coloured by world axis (x red, y green, z blue, each with an arrow head at
its end: the axis' positive sense; grey and crossed in its axis' colour where the calibration left
it out), the known lengths clicked in it (white, with their length), the marker observations as
rings labelled with the marker's name, the pins as crosses and the edge observations as magenta
lines. Drawing is by Pillow on the pixels, with no time in the file: the same project gives the
same PNG bytes. A pixel coordinate (origin at the photo's top-left corner) is drawn at
:func:`on_image`.
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
#: A vanishing segment the calibration left out (its axis' colour crosses it); a known length.
REJECTED_RGB = (150, 150, 150)
KNOWN_RGB = (255, 255, 255)


def photo_image(project: Project, index: int, width: int) -> tuple[Any, float]:
    """Photo ``index`` of ``$.photos`` decoded as every consumer decodes it, reduced to ``width``
    pixels wide (a PIL image), and the scale from the photo's pixels to the image's."""
    from PIL import Image

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
    return Image.fromarray(pixels, "RGB").resize((width, height), Image.Resampling.LANCZOS), s


def on_image(u: float, v: float, s: float) -> tuple[float, float]:
    """Where the photo's pixel coordinate (u, v) (origin at the photo's top-left corner) falls on
    its image reduced by ``s``, in Pillow's drawing coordinates (whole numbers at pixel centres)."""
    return (u * s - 0.5, v * s - 0.5)


def label(draw: Any, at: tuple[float, float], text: str, colour: tuple[int, int, int], font: Any, width: int,
          height: int) -> None:
    """``text`` on a black box with its top left at ``at``, moved inside the image where it would leave it."""
    box = draw.textbbox(at, text, font=font)
    dx = min(0.0, width - 2 - box[2]) + max(0.0, 2 - box[0])
    dy = min(0.0, height - 2 - box[3]) + max(0.0, 2 - box[1])
    at = (at[0] + dx, at[1] + dy)
    box = draw.textbbox(at, text, font=font)
    draw.rectangle((box[0] - 2, box[1] - 2, box[2] + 2, box[3] + 2), fill=(0, 0, 0))
    draw.text(at, text, fill=colour, font=font)


def marked_photo(project: Project, index: int, width: int) -> tuple[NDArray[np.uint8], dict[str, int]]:
    """Photo ``index`` of ``$.photos`` at ``width`` pixels wide with its marks drawn; and the count
    of each kind of mark drawn."""
    from PIL import ImageDraw, ImageFont

    photo = project.data["photos"][index]
    img, s = photo_image(project, index, width)
    height = img.height
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default(size=max(14, width // 48))
    lw = max(1, round(width / 480))
    counts = {"segments": 0, "rejected": 0, "markers": 0, "pins": 0, "edges": 0, "known_lengths": 0}
    rejected = _rejected(project, photo["id"])

    def pt(u: float, v: float) -> tuple[float, float]:
        return on_image(u, v, s)

    for axis, rows in sorted((photo.get("vanishing_segments") or {}).items()):
        colour = AXIS_RGB.get(axis, (255, 255, 255))
        for k_row, row in enumerate(rows):
            xy = [pt(row[k], row[k + 1]) for k in range(0, len(row) - 1, 2)]
            if k_row in rejected.get(axis, ()):  # left out of the calibration: grey, crossed at its middle
                draw.line(xy, fill=REJECTED_RGB, width=lw)
                mid = np.mean(np.asarray(xy, float), axis=0)
                r = 3 * lw + 2
                draw.line([(mid[0] - r, mid[1] - r), (mid[0] + r, mid[1] + r)], fill=colour, width=lw + 1)
                draw.line([(mid[0] - r, mid[1] + r), (mid[0] + r, mid[1] - r)], fill=colour, width=lw + 1)
                counts["rejected"] += 1
                continue
            draw.line(xy, fill=colour, width=lw + 1)
            _arrow_head(draw, xy[-2], xy[-1], colour, 4 * lw + 4)
            counts["segments"] += 1
    for k in project.data.get("known_lengths") or []:
        if k["photo"] != photo["id"]:
            continue
        a, b = pt(*k["ends"][0]), pt(*k["ends"][1])
        draw.line([a, b], fill=KNOWN_RGB, width=lw + 1)
        for end in (a, b):
            _tick(draw, end, np.subtract(b, a), KNOWN_RGB, 4 * lw + 3, lw + 1)
        sigma = f" ± {float(k['sigma']):g}" if k.get("sigma") is not None else ""
        label(draw, (max(a[0], b[0]) + 6, (a[1] + b[1]) / 2), f"known {float(k['length']):g}{sigma} m",
              KNOWN_RGB, font, width, height)
        counts["known_lengths"] += 1
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
        label(draw, at, name, MARKER_RGB, font, width, height)
        counts["markers"] += 1
    return np.asarray(img), counts


def _rejected(project: Project, photo: str) -> dict[str, set[int]]:
    """Axis → the indices of the photo's segments its calibration left out (``vanishing_points[axis].rejected``)."""
    cam = ((project.data.get("calibration") or {}).get("cameras") or {}).get(photo) or {}
    vps = cam.get("vanishing_points") or {}
    return {a: {int(r["segment"]) for r in (vp.get("rejected") or [])} for a, vp in vps.items()
            if isinstance(vp, dict)}


def _tick(draw: Any, at: Sequence[float], along: Any, colour: tuple[int, int, int], size: float,
          width: int) -> None:
    """A short bar across the direction ``along`` at ``at``: the end of a drawn length."""
    d = np.asarray(along, float)
    n = float(np.hypot(d[0], d[1]))
    if n < 1e-9:
        return
    side = np.array([-d[1], d[0]]) / n * size / 2
    draw.line([tuple(np.asarray(at) - side), tuple(np.asarray(at) + side)], fill=colour, width=width)


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
