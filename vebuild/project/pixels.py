"""Pixel formats (layer 3): every image mode Pillow hands back turned into 8-bit RGB, or refused by name.

:func:`rgb_image` is the one place where decoded pixels become the 8-bit RGB that every stage uses
(:func:`vebuild.project.images.decode_photo` for photos, the atlas pages' reader for those);
:func:`check_pixel_format` is its refusal alone, run wherever a photo is decoded whole to check it
(`vebuild check`, `vebuild new`, every command's load), so that a photo accepted there is one that
every stage decodes. The rules, by Pillow mode (scenes/FORMAT.md, "Photo pixel formats"):

- ``1``, ``L``: grey, r = g = b (``1``: 0 or 255); ``P``: the palette's colours.
- ``RGB``, ``RGBX``: as stored. A 16-bit RGB PNG or TIFF reaches vebuild as ``RGB``, Pillow keeping
  each sample's high byte (v >> 8, within one level of v · 255 / 65535).
- ``I;16``, ``I;16L``, ``I;16B``, ``I;16N`` (16-bit grey): v · 255 / 65535, rounded to the nearest
  level (0 → 0, 65535 → 255), the same for r, g and b; (65535 − v) · 255 / 65535 where a TIFF says
  0 is white (PhotometricInterpretation 0, which Pillow undoes for 8 bits but not for 16).
- ``I`` (32-bit integers): as 16-bit grey where Pillow read a 16-bit PGM or PPM (it scales the
  file's maximum value to 65535); from any other file refused, as ``F`` (32-bit floats) always is:
  such pixels have no defined black and white, and vebuild does not guess them. So is a TIFF
  whose samples are not unsigned integers (SampleFormat), whatever mode Pillow reads it as (a
  signed 8-bit TIFF comes back as ``L``, -1 as 255).
- ``LA``, ``La``, ``PA``, ``RGBA``, ``RGBa``, and ``P``, ``1``, ``L``, ``RGB`` or 16-bit grey with a
  transparent colour: the alpha is dropped where every pixel is opaque; an image with any pixel not
  fully opaque is refused, since the colour there is not the scene's and vebuild does not guess what
  lies behind it. A transparent colour is compared with the stored values (16-bit grey's own, not
  Pillow's 8-bit ones); a 16-bit RGB PNG's by its high bytes, all that Pillow keeps, so that a
  pixel that may be that colour refuses the image.
- ``CMYK``: device CMYK, r = (255 − c)(255 − k) / 255 and so on (an embedded ICC profile is not
  applied, as for every photo: vebuild uses the values as stored; Pillow undoes Adobe's inverted
  CMYK JPEGs when it reads them).
- ``YCbCr``: JPEG's (JFIF's full-range ITU-R BT.601) equations.
- ``LAB``: CIE L*a*b* (D50; L* 0–100 stored as 0–255, a* and b* as signed bytes) to sRGB by
  LittleCMS, relative colorimetric, computed for each pixel (its default table, interpolated, is
  up to 25 levels off in dark channels); colours outside sRGB are clipped.
- ``HSV``: the hexcone model (h 0–255 for 0–360°), as Python's colorsys.
- any other mode: refused by name.

Only an image's first frame is read (an animated GIF or PNG, a multi-page TIFF, an MPO's first
picture), as every viewer first shows it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from PIL import Image

from vebuild.errors import ProjectError

#: Pillow modes of 16-bit grey, decoded v · 255 / 65535.
SIXTEEN_BIT_GREY = frozenset({"I;16", "I;16L", "I;16B", "I;16N"})
#: Pillow modes that carry an alpha channel.
ALPHA = frozenset({"LA", "La", "PA", "RGBA", "RGBa"})
#: Pillow modes converted by Pillow's own conversion as they are.
CONVERTED = frozenset({"1", "L", "P", "RGB", "RGBX", "CMYK", "YCbCr", "HSV"})
#: What each mode holds, as messages name it.
DESCRIBED = {
    "1": "1-bit black and white", "L": "8-bit grey", "LA": "8-bit grey with alpha",
    "La": "8-bit grey with premultiplied alpha", "P": "a palette of colours", "PA": "a palette with alpha",
    "RGB": "8-bit RGB", "RGBX": "8-bit RGB with padding", "RGBA": "8-bit RGB with alpha",
    "RGBa": "8-bit RGB with premultiplied alpha", "CMYK": "8-bit CMYK", "YCbCr": "8-bit YCbCr",
    "LAB": "8-bit CIE L*a*b*", "HSV": "8-bit HSV", "I": "32-bit integers", "F": "32-bit floating point",
    **{m: "16-bit grey" for m in SIXTEEN_BIT_GREY},
}
#: The 16-bit level → 8-bit level table: round(v · 255 / 65535) = round(v / 257), halves up.
_SIXTEEN_TO_EIGHT = ((2 * np.arange(65536, dtype=np.uint32) + 257) // 514).astype(np.uint8)
#: Pixels per band when 16-bit grey is scaled (a few MB at a time).
_BAND_PIXELS = 1 << 20
#: Formats whose ``I`` images Pillow scales to 0–65535 (a PGM or PPM of more than 8 bits).
_SIXTEEN_BIT_AS_I = frozenset({"PPM"})
#: TIFF's SampleFormat values (tag 339) other than unsigned integers, as messages name them.
_SAMPLE_FORMATS = {2: "signed integer", 3: "floating-point", 4: "undefined", 5: "complex integer",
                   6: "complex floating-point"}
_WHAT_TO_DO = ("save a copy with 8 or 16 bits per sample in an image editor, choosing there which values are "
               "black and white, and add that copy")


def pixel_format(img: Image.Image) -> str:
    """The image's pixel format as messages name it: ``8-bit grey (Pillow mode 'L')``."""
    described = DESCRIBED.get(img.mode)
    return f"{described} (Pillow mode {img.mode!r})" if described else f"Pillow mode {img.mode!r}"


def check_pixel_format(img: Image.Image, file: Any, where: str, shown: str, noun: str = "photo",
                       head: bytes = b"") -> None:
    """Refuse an image (opened, decoded) whose pixels vebuild cannot turn into 8-bit RGB as
    :func:`rgb_image` does. ``head``: the file's first bytes (at least 25), by which a 16-bit PNG
    is told (Pillow's image no longer says so).

    Raises
    ------
    ProjectError naming ``file``, ``where``, the image (``shown``) and its pixel format: a mode
    with no defined black and white (``F``; ``I`` but from a 16-bit PGM or PPM), one Pillow names
    but vebuild does not know, or any pixel not fully opaque.
    """
    mode = img.mode
    if mode == "F" or (mode == "I" and img.format not in _SIXTEEN_BIT_AS_I):
        raise ProjectError(file, where, f"the {noun} {shown} has pixels of {pixel_format(img)}, which have no "
                           f"defined black and white: vebuild cannot tell which values are dark and which light, "
                           f"and will not guess. Expected 8 or 16 bits per sample (grey, RGB, palette, CMYK, "
                           f"YCbCr, L*a*b*): {_WHAT_TO_DO}")
    signed = sorted({int(v) for v in _tiff_tag(img, 339)} - {1})
    if signed:  # Pillow reads a signed 8-bit TIFF as L, -1 as 255
        kinds = ", ".join(_SAMPLE_FORMATS.get(v, f"undefined ({v})") for v in signed)
        raise ProjectError(file, where, f"the {noun} {shown} is a TIFF of {kinds} samples (its SampleFormat, tag "
                           f"339), which Pillow hands back as {pixel_format(img)} with the wrong values; expected "
                           f"unsigned integer samples: {_WHAT_TO_DO}")
    if mode == "I":
        extrema: Any = img.getextrema()  # one band: (lowest, highest)
        low, high = extrema
        if low < 0 or high > 65535:  # not what Pillow makes of a PGM; refused rather than clipped
            raise ProjectError(file, where, f"the {noun} {shown} has pixels of {pixel_format(img)} from "
                               f"{low} to {high}, expected 0 to 65535 (a 16-bit PGM or PPM): {_WHAT_TO_DO}")
    elif mode not in CONVERTED | ALPHA | SIXTEEN_BIT_GREY | {"LAB"}:
        raise ProjectError(file, where, f"the {noun} {shown} has pixels of {pixel_format(img)}, which vebuild cannot "
                           "turn into RGB; expected grey, RGB, palette, CMYK, YCbCr, L*a*b* or HSV of 8 or 16 "
                           "bits per sample: save a copy as an 8-bit RGB JPEG, PNG or TIFF and add that copy")
    unseen, maybe = _not_opaque(img, head)
    if unseen:
        total = img.size[0] * img.size[1]
        raise ProjectError(file, where, f"the {noun} {shown} has {unseen} of its {total} pixels {maybe}not fully "
                           f"opaque (pixel format {pixel_format(img)}, with transparency): the colour stored there "
                           "is not what the camera saw through them, and vebuild will not guess what lies behind. "
                           "Expected an opaque image: flatten a copy onto a background in an image editor (e.g. "
                           "`magick photo.png -background white -alpha remove -alpha off copy.png`) if that is "
                           "right for the evidence, and add that copy")


def _tiff_tag(img: Image.Image, tag: int) -> tuple[Any, ...]:
    """A TIFF tag's values (() where the image is no TIFF or has no such tag): 339 SampleFormat (1
    unsigned, 2 signed, 3 floating point; absent: unsigned), 262 PhotometricInterpretation."""
    tags = getattr(img, "tag_v2", None) if img.format == "TIFF" else None
    value = tags.get(tag, ()) if tags is not None else ()
    return value if isinstance(value, tuple) else (value,)


def _not_opaque(img: Image.Image, head: bytes) -> tuple[int, str]:
    """How many pixels are not fully opaque (by an alpha channel, or a transparent colour key), and
    "" or, where that can only be bounded, "perhaps "."""
    if img.mode in ALPHA:
        alpha = img.getchannel(len(img.getbands()) - 1)  # "A", or "a" where premultiplied
        return sum(alpha.histogram()[:255]), ""
    key = img.info.get("transparency")
    if key is None:
        return 0, ""
    if img.mode in SIXTEEN_BIT_GREY or img.mode == "I":  # Pillow's own conversion would compare 8-bit values
        return int(np.count_nonzero(np.asarray(img) == key)), ""
    if img.mode == "RGB" and isinstance(key, tuple) and _png_bit_depth(head) == 16:
        # Pillow keeps a 16-bit sample's high byte: a pixel is the key colour only if its high bytes are.
        high = np.array([int(k) >> 8 for k in key], np.uint8)
        return int(np.count_nonzero((np.asarray(img) == high).all(axis=-1))), "perhaps "
    return sum(img.convert("RGBA").getchannel("A").histogram()[:255]), ""


def _png_bit_depth(head: bytes) -> int | None:
    """A PNG's bits per sample, from its IHDR chunk (the file's first 25 bytes), else None."""
    if len(head) >= 25 and head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
        return head[24]
    return None


def rgb_image(img: Image.Image, file: Any, where: str, shown: str, noun: str = "photo",
              head: bytes = b"") -> Image.Image:
    """An opened image's pixels as an 8-bit RGB image, by the rules of this module (the image
    itself where it is RGB already). Raises as :func:`check_pixel_format`."""
    check_pixel_format(img, file, where, shown, noun, head)
    if img.mode in SIXTEEN_BIT_GREY or img.mode == "I":
        w, h = img.size
        grey = np.empty((h, w), np.uint8)
        band = max(1, _BAND_PIXELS // max(1, w))
        # A TIFF whose 0 is white (PhotometricInterpretation 0): Pillow inverts 8-bit grey, not 16-bit.
        table = _SIXTEEN_TO_EIGHT[::-1] if _tiff_tag(img, 262) == (0,) else _SIXTEEN_TO_EIGHT
        for y0 in range(0, h, band):
            grey[y0:y0 + band] = table[np.asarray(img.crop((0, y0, w, min(h, y0 + band))))]
        return Image.fromarray(grey, "L").convert("RGB")
    if img.mode == "LAB":
        return _lab_to_srgb(img, file, where, shown, noun)
    if img.mode == "La":  # Pillow converts premultiplied grey to RGB only through LA
        img = img.convert("LA")
    return img if img.mode == "RGB" else img.convert("RGB")


def _lab_to_srgb(img: Image.Image, file: Any, where: str, shown: str, noun: str) -> Image.Image:
    try:
        from PIL import ImageCms

        transform = ImageCms.buildTransform(ImageCms.createProfile("LAB"), ImageCms.createProfile("sRGB"), "LAB",
                                            "RGB", renderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC,
                                            flags=ImageCms.Flags.NOOPTIMIZE)
    except (ImportError, OSError, ValueError) as e:  # a Pillow built without LittleCMS
        raise ProjectError(file, where, f"the {noun} {shown} has pixels of {pixel_format(img)}, which this Pillow "
                           f"cannot convert to RGB ({e}); expected a Pillow with LittleCMS (every Pillow wheel has "
                           "it), or save a copy as 8-bit RGB and add that copy") from None
    out: Image.Image = ImageCms.applyTransform(img, transform)  # type: ignore[assignment]  # None only in place
    return out
