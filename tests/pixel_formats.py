"""Images of every pixel format Pillow hands back, with known values and the RGB each must decode to
(or the refusal it must meet): shared by test_pixel_formats.py, the bad-input corpus and the fuzz.

Each maker takes a random generator and a size and returns a :class:`Sample`: the file's bytes (or,
for the modes no file format writes, the opened image), the Pillow mode the decoder meets, and the
expected RGB computed here from the stored values by the published formulas (not by Pillow's own
conversion), with the tolerance that rounding allows, or None where the image must be refused.
"""

from __future__ import annotations

import colorsys
import io
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import tifffile
from numpy.typing import NDArray
from PIL import Image

#: Levels a decoded value may differ from the exact value by where the decoder rounds once (to the
#: nearest 8-bit level).
ROUNDED = 0.5
#: Pillow's 16-bit RGB keeps each sample's high byte: floor(v / 256) is within one level of v / 257.
HIGH_BYTE = 1.0
#: Pillow's YCbCr → RGB works in fixed point (measured: at most 0.99 levels from JFIF's equations).
YCBCR = 1.0
#: LittleCMS's L*a*b* → sRGB, computed for each pixel (measured: at most 0.67 levels in gamut).
LAB = 1.0
#: A PGM of maxval m is scaled by Pillow to 0–65535, then by vebuild to 0–255: two roundings.
PGM_SCALED = ROUNDED + 0.5 * 255 / 65535


@dataclass(frozen=True)
class Sample:
    name: str
    mode: str                           # the Pillow mode the decoder meets
    data: bytes | None                  # the file's bytes; None: no format writes it (``image`` then)
    expected: NDArray[np.float64] | None  # (h, w, 3) RGB, exact; None: refused
    tolerance: float = 0.0              # levels
    refusal: str = ""                   # words the refusal names, besides the file and the mode
    image: Image.Image | None = None

    def opened(self) -> Image.Image:
        return Image.open(io.BytesIO(self.data)) if self.data is not None else self.image  # type: ignore[return-value]


Maker = Callable[[np.random.Generator, int, int], Sample]


def saved(img: Image.Image, fmt: str, **kw: object) -> bytes:
    b = io.BytesIO()
    img.save(b, fmt, **kw)
    return b.getvalue()


def _tiff(a: NDArray, **kw: object) -> bytes:
    b = io.BytesIO()
    tifffile.imwrite(b, a, **kw)
    return b.getvalue()


def _grey(v: NDArray) -> NDArray[np.float64]:
    return np.repeat(v.astype(np.float64)[..., None], 3, axis=2)


def png16(a: NDArray[np.uint16], colour_type: int, key: tuple[int, ...] | None = None) -> bytes:
    """A 16-bit PNG written here (Pillow writes 16-bit grey but not 16-bit RGB): grey (0) or RGB (2),
    with the transparent colour ``key`` (a tRNS chunk) where given."""
    h, w = a.shape[:2]
    rows = b"".join(b"\x00" + a[y].astype(">u2").tobytes() for y in range(h))

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, colour_type, 0, 0, 0))
            + (chunk(b"tRNS", struct.pack(f">{len(key)}H", *key)) if key else b"")
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def _u8(rng: np.random.Generator, *shape: int) -> NDArray[np.uint8]:
    return rng.integers(0, 256, shape, dtype=np.uint8)


def _u16(rng: np.random.Generator, *shape: int) -> NDArray[np.uint16]:
    a = rng.integers(0, 65536, shape, dtype=np.uint16)
    a.flat[:2] = (0, 65535)[: a.size]  # black and white, where the scale is pinned
    return a


def _palette(rng: np.random.Generator, h: int, w: int) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    return rng.integers(0, 16, (h, w), dtype=np.uint8), _u8(rng, 256, 3)


def _p_image(index: NDArray[np.uint8], palette: NDArray[np.uint8]) -> Image.Image:
    img = Image.fromarray(index, "P")
    img.putpalette(palette.tobytes())
    return img


# -- accepted ----------------------------------------------------------------------------------------


def one_bit(rng: np.random.Generator, h: int, w: int) -> Sample:
    bits = rng.integers(0, 2, (h, w)).astype(bool)
    return Sample("1 (PNG)", "1", saved(Image.fromarray(bits), "PNG"), _grey(bits * 255.0))


def grey_l(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w)
    return Sample("L (PNG)", "L", saved(Image.fromarray(a, "L"), "PNG"), _grey(a))


def grey_la_opaque(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w)
    la = np.stack([a, np.full_like(a, 255)], -1)
    return Sample("LA opaque (PNG)", "LA", saved(Image.fromarray(la, "LA"), "PNG"), _grey(a))


def palette_p(rng: np.random.Generator, h: int, w: int) -> Sample:
    index, palette = _palette(rng, h, w)
    return Sample("P (PNG)", "P", saved(_p_image(index, palette), "PNG"), palette[index].astype(np.float64))


def palette_pa_opaque(rng: np.random.Generator, h: int, w: int) -> Sample:
    index, palette = _palette(rng, h, w)
    pa = Image.merge("PA", [_p_image(index, palette).getchannel(0), Image.new("L", (w, h), 255)])
    pa.putpalette(palette.tobytes())
    return Sample("PA opaque (TIFF)", "PA", saved(pa, "TIFF"), palette[index].astype(np.float64))


def grey16_png(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u16(rng, h, w)
    return Sample("I;16 (16-bit grey PNG)", "I;16", png16(a, 0), _grey(a * 255.0 / 65535), ROUNDED)


def grey16_tiff_big_endian(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u16(rng, h, w)
    return Sample("I;16B (16-bit grey TIFF, big-endian)", "I;16B", _tiff(a, byteorder=">"),
                  _grey(a * 255.0 / 65535), ROUNDED)


def grey16_tiff_min_is_white(rng: np.random.Generator, h: int, w: int) -> Sample:
    """16-bit grey whose 0 is white (PhotometricInterpretation 0), as some scanners write."""
    a = _u16(rng, h, w)
    return Sample("I;16 (16-bit grey TIFF, 0 is white)", "I;16", _tiff(a, photometric="miniswhite"),
                  _grey((65535 - a) * 255.0 / 65535), ROUNDED)


def grey_tiff_min_is_white(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w)
    return Sample("L (8-bit grey TIFF, 0 is white)", "L", _tiff(a, photometric="miniswhite"), _grey(255 - a))


def grey16_pgm(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u16(rng, h, w)
    data = f"P5 {w} {h} 65535\n".encode() + a.astype(">u2").tobytes()
    return Sample("I (16-bit PGM)", "I", data, _grey(a * 255.0 / 65535), ROUNDED)


def grey12_pgm(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = rng.integers(0, 4096, (h, w), dtype=np.uint16)
    data = f"P5 {w} {h} 4095\n".encode() + a.astype(">u2").tobytes()
    return Sample("I (12-bit PGM, maxval 4095)", "I", data, _grey(a * 255.0 / 4095), PGM_SCALED)


def rgb8(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w, 3)
    return Sample("RGB (PNG)", "RGB", saved(Image.fromarray(a, "RGB"), "PNG"), a.astype(np.float64))


def rgb16_png(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u16(rng, h, w, 3)
    return Sample("16-bit RGB (PNG)", "RGB", png16(a, 2), a * 255.0 / 65535, HIGH_BYTE)


def rgb16_tiff(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u16(rng, h, w, 3)
    return Sample("16-bit RGB (TIFF)", "RGB", _tiff(a, photometric="rgb"), a * 255.0 / 65535, HIGH_BYTE)


def rgb16_png_key_unused(rng: np.random.Generator, h: int, w: int) -> Sample:
    """A 16-bit RGB PNG with a transparent colour that no pixel has, not even in its high bytes."""
    a = _u16(rng, h, w, 3)
    a[..., 0] |= 0x8000  # every red high byte ≥ 128; the key's red is 0x12xx
    return Sample("16-bit RGB with an unused transparent colour (PNG)", "RGB", png16(a, 2, (0x1234, 7, 9)),
                  a * 255.0 / 65535, HIGH_BYTE)


def rgba_opaque(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w, 3)
    rgba = np.concatenate([a, np.full((h, w, 1), 255, np.uint8)], -1)
    return Sample("RGBA opaque (PNG)", "RGBA", saved(Image.fromarray(rgba, "RGBA"), "PNG"), a.astype(np.float64))


def cmyk_tiff(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w, 4).astype(np.float64)
    rgb = (255 - a[..., :3]) * (255 - a[..., 3:]) / 255
    return Sample("CMYK (TIFF)", "CMYK", saved(Image.fromarray(a.astype(np.uint8), "CMYK"), "TIFF"), rgb, ROUNDED)


def cmyk_jpeg(rng: np.random.Generator, h: int, w: int) -> Sample:
    """A CMYK JPEG (stored inverted, with Adobe's marker, as Photoshop writes it) of one colour, which
    JPEG at quality 100 keeps exactly."""
    c = _u8(rng, 4).astype(np.float64)
    rgb = np.broadcast_to((255 - c[:3]) * (255 - c[3]) / 255, (h, w, 3))
    data = saved(Image.new("CMYK", (w, h), tuple(int(v) for v in c)), "JPEG", quality=100)
    return Sample("CMYK (JPEG, Adobe)", "CMYK", data, rgb, ROUNDED)


def ycbcr_tiff(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w, 3)
    y, cb, cr = (a[..., i].astype(np.float64) for i in range(3))
    rgb = np.stack([y + 1.402 * (cr - 128), y - 0.344136 * (cb - 128) - 0.714136 * (cr - 128),
                    y + 1.772 * (cb - 128)], -1)
    return Sample("YCbCr (TIFF)", "YCbCr", saved(Image.fromarray(a, "YCbCr"), "TIFF"), np.clip(rgb, 0, 255), YCBCR)


def lab_to_srgb(lab: NDArray[np.float64]) -> NDArray[np.float64]:
    """CIE L*a*b* (D50) → sRGB levels (0–255, clipped): CIE 15 to XYZ, Bradford to D65, IEC 61966-2-1."""
    fy = (lab[..., 0] + 16) / 116
    f = np.stack([fy + lab[..., 1] / 500, fy, fy - lab[..., 2] / 200], -1)
    xyz = np.where(f > 6 / 29, f ** 3, 3 * (6 / 29) ** 2 * (f - 4 / 29)) * np.array([0.9642, 1.0, 0.8249])
    bradford = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]])
    d50, d65 = np.array([0.9642, 1.0, 0.8249]), np.array([0.95047, 1.0, 1.08883])
    adapt = np.linalg.inv(bradford) @ np.diag((bradford @ d65) / (bradford @ d50)) @ bradford
    to_rgb = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])
    lin = np.clip(xyz @ (to_rgb @ adapt).T, 0.0, 1.0)
    return np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055) * 255


def lab_tiff(rng: np.random.Generator, h: int, w: int) -> Sample:
    """L*a*b* colours inside sRGB (where the clipping of both sides could differ they are left out)."""
    values = np.empty((0, 3))
    while len(values) < h * w:
        draw = np.stack([rng.uniform(0, 255, 4 * h * w).round(), rng.integers(-100, 101, 4 * h * w),
                         rng.integers(-100, 101, 4 * h * w)], -1)
        lab = draw * [100 / 255, 1, 1]
        rgb = lab_to_srgb(lab)
        inside = ((rgb > 0.5) & (rgb < 254.5)).all(-1)
        values = np.concatenate([values, draw[inside]])
    stored = values[: h * w].reshape(h, w, 3).astype(np.int64)
    raw = np.stack([stored[..., 0], stored[..., 1] % 256, stored[..., 2] % 256], -1).astype(np.uint8)
    expected = lab_to_srgb(stored * np.array([100 / 255, 1, 1]))
    return Sample("LAB (TIFF CIELab)", "LAB", _tiff(raw, photometric="cielab"), expected, LAB)


def hsv_in_memory(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w, 3)
    rgb = np.array([[colorsys.hsv_to_rgb(*(p / 255.0)) for p in row] for row in a.astype(np.float64)]) * 255
    return Sample("HSV (in memory)", "HSV", None, rgb.reshape(h, w, 3), ROUNDED, image=Image.fromarray(a, "HSV"))


def rgbx_in_memory(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w, 4)
    return Sample("RGBX (in memory)", "RGBX", None, a[..., :3].astype(np.float64), image=Image.fromarray(a, "RGBX"))


def la_premultiplied_opaque(rng: np.random.Generator, h: int, w: int) -> Sample:
    """Premultiplied alpha (La, RGBa), opaque: what no file holds but Pillow can hand back."""
    a = _u8(rng, h, w, 2)
    a[..., 1] = 255
    return Sample("La opaque (in memory)", "La", None, _grey(a[..., 0]), image=Image.fromarray(a, "La"))


def rgba_premultiplied_opaque(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w, 4)
    a[..., 3] = 255
    return Sample("RGBa opaque (in memory)", "RGBa", None, a[..., :3].astype(np.float64),
                  image=Image.fromarray(a, "RGBa"))


def animated_gif(rng: np.random.Generator, h: int, w: int) -> Sample:
    frames = [Image.fromarray(_u8(rng, h, w, 3) // 51 * 51, "RGB") for _ in range(3)]  # 216 web-safe colours
    data = saved(frames[0], "GIF", save_all=True, append_images=frames[1:], duration=100, loop=0)
    return Sample("animated GIF (its first frame)", "P", data, np.asarray(frames[0]).astype(np.float64))


def animated_png(rng: np.random.Generator, h: int, w: int) -> Sample:
    frames = [Image.fromarray(_u8(rng, h, w, 3), "RGB") for _ in range(3)]
    data = saved(frames[0], "PNG", save_all=True, append_images=frames[1:], duration=100)
    return Sample("animated PNG (its first frame)", "RGB", data, np.asarray(frames[0]).astype(np.float64))


# -- refused -----------------------------------------------------------------------------------------


def float_tiff(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = rng.uniform(0, 1, (h, w)).astype(np.float32)
    return Sample("F (32-bit float TIFF)", "F", _tiff(a), None, refusal="black and white")


def int32_tiff(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = rng.integers(0, 1 << 20, (h, w), dtype=np.int32)
    return Sample("I (32-bit integer TIFF)", "I", _tiff(a), None, refusal="black and white")


def int16_signed_tiff(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = rng.integers(-32768, 32768, (h, w), dtype=np.int16)
    return Sample("I (signed 16-bit TIFF)", "I", _tiff(a), None, refusal="black and white")


def int8_signed_tiff(rng: np.random.Generator, h: int, w: int) -> Sample:
    """Signed 8-bit samples, which Pillow hands back as L (-1 as 255)."""
    a = rng.integers(-128, 128, (h, w), dtype=np.int8)
    return Sample("L (signed 8-bit TIFF)", "L", _tiff(a), None, refusal="signed integer samples")


def rgba_transparent(rng: np.random.Generator, h: int, w: int) -> Sample:
    rgba = _u8(rng, h, w, 4)
    rgba[..., 3] = 255
    rgba[0, 0, 3] = 0
    return Sample("RGBA with a transparent pixel (PNG)", "RGBA", saved(Image.fromarray(rgba, "RGBA"), "PNG"), None,
                  refusal="1 of its")


def la_translucent(rng: np.random.Generator, h: int, w: int) -> Sample:
    la = _u8(rng, h, w, 2)
    la[..., 1] = np.minimum(la[..., 1], 254)
    return Sample("LA translucent (PNG)", "LA", saved(Image.fromarray(la, "LA"), "PNG"), None,
                  refusal=f"{h * w} of its")


def pa_translucent(rng: np.random.Generator, h: int, w: int) -> Sample:
    index, palette = _palette(rng, h, w)
    pa = Image.merge("PA", [_p_image(index, palette).getchannel(0), Image.new("L", (w, h), 128)])
    pa.putpalette(palette.tobytes())
    return Sample("PA translucent (TIFF)", "PA", saved(pa, "TIFF"), None, refusal=f"{h * w} of its")


def palette_transparent_index(rng: np.random.Generator, h: int, w: int) -> Sample:
    index, palette = _palette(rng, h, w)
    index[-1, -1] = 200  # the one transparent colour, used once
    data = saved(_p_image(index, palette), "PNG", transparency=200)
    return Sample("P with a transparent colour (PNG)", "P", data, None, refusal="1 of its")


def grey16_key_used(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u16(rng, h, w) | 1  # odd values only; the key is even, and used once
    a[-1, -1] = 1000
    return Sample("16-bit grey with a transparent colour (PNG)", "I;16", png16(a, 0, (1000,)), None,
                  refusal="1 of its")


def rgb16_key_maybe_used(rng: np.random.Generator, h: int, w: int) -> Sample:
    """A 16-bit RGB PNG with a transparent colour: Pillow keeps only the high bytes, so a pixel whose
    high bytes are the key's may be transparent (here one is) and the photo is refused."""
    a = _u16(rng, h, w, 3)
    a[..., 0] |= 0x8000
    a[-1, -1] = (0x1234, 7, 9)
    return Sample("16-bit RGB with a transparent colour (PNG)", "RGB", png16(a, 2, (0x1234, 7, 9)), None,
                  refusal="1 of its")


def rgb_key_used(rng: np.random.Generator, h: int, w: int) -> Sample:
    a = _u8(rng, h, w, 3)
    a[..., 0] |= 0x80
    a[0, -1] = (1, 2, 3)
    return Sample("RGB with a transparent colour (PNG)", "RGB",
                  saved(Image.fromarray(a, "RGB"), "PNG", transparency=(1, 2, 3)), None, refusal="1 of its")


ACCEPTED: list[Maker] = [
    one_bit, grey_l, grey_la_opaque, palette_p, palette_pa_opaque, grey16_png, grey16_tiff_big_endian,
    grey16_tiff_min_is_white, grey_tiff_min_is_white, grey16_pgm,
    grey12_pgm, rgb8, rgb16_png, rgb16_tiff, rgb16_png_key_unused, rgba_opaque, cmyk_tiff, cmyk_jpeg, ycbcr_tiff,
    lab_tiff, hsv_in_memory, rgbx_in_memory, la_premultiplied_opaque, rgba_premultiplied_opaque, animated_gif,
    animated_png]
REFUSED: list[Maker] = [
    float_tiff, int32_tiff, int16_signed_tiff, int8_signed_tiff, rgba_transparent, la_translucent, pa_translucent,
    palette_transparent_index, grey16_key_used, rgb16_key_maybe_used, rgb_key_used]
