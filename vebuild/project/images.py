"""Image files (layer 3): opened bounded in pixels and decoded whole, hashed, their EXIF read.

Every image vebuild reads (photos, atlas pages) is opened through :func:`open_image`, so that an
image too large, damaged or truncated is a :class:`~vebuild.errors.ProjectError` naming the file
and the field, before its pixels are decoded where it is too large.

A photo's pixels are decoded for every consumer (texture extraction, the modelling screen, the
viewer, photo-camera renders) by one function, :func:`decode_photo`: turned as the camera meant
(EXIF orientation 1–8, so that the photo's ``width``, ``height`` and every mark are in the displayed
orientation), its pixel format turned into 8-bit RGB or refused by name (:mod:`.pixels`), and a
camera RAW file (DNG, NEF, CR2, ARW, ...) developed by LibRaw (rawpy). The photo's SHA-256 is always
its file's bytes: vebuild never alters a photo.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import os
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import PIL
from numpy.typing import NDArray
from PIL import Image, UnidentifiedImageError

from vebuild.errors import ProjectError
from vebuild.resources import cache_dir

from .atomic import write_text
from .pixels import check_pixel_format, rgb_image

#: The most pixels an image vebuild reads may have: 120 megapixels, more than the largest camera
#: sensor in use (100 MP) and below Pillow's decompression-bomb guard (179 MP). Larger images are
#: refused before they are decoded.
MAX_IMAGE_PIXELS = 120_000_000
_CHUNK = 1 << 20
#: The bytes of a file's start that tell what Pillow's decoded image no longer does (a PNG's depth).
_HEAD = 32


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
    except UnidentifiedImageError:  # its message names the in-memory file (an address): a message of its own
        raise ProjectError(file, where, f"cannot open {shown} as an image: expected an image file (PNG, JPEG, "
                           "TIFF, ...); its contents are of no image format vebuild reads") from None
    except (OSError, ValueError, SyntaxError) as e:
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




# --------------------------------------------------------------------------------------------------
# Photos: their size as displayed, their pixels, their EXIF

#: File name endings of camera RAW files, developed through LibRaw (rawpy) rather than Pillow.
#: DNG is tested (tests/test_exif_raw.py writes one); the others are the formats LibRaw reads.
RAW_SUFFIXES = frozenset({".dng", ".nef", ".nrw", ".cr2", ".cr3", ".crw", ".arw", ".srf", ".sr2", ".raf",
                          ".orf", ".rw2", ".pef", ".srw", ".3fr", ".iiq", ".erf", ".mos", ".kdc", ".dcr",
                          ".mrw", ".x3f", ".rwl"})
#: Pixels per band when a decoded photo is copied into its array (a few MB at a time), so that no
#: second copy of the whole photo is made (np.asarray of the image would make two).
DECODE_BAND_PIXELS = 1 << 20
_ORIENTATION = 0x0112
#: The EXIF orientations (tag 274) and what each means.
ORIENTATIONS = {1: "upright", 2: "mirrored left to right", 3: "upside down", 4: "mirrored top to bottom",
                5: "mirrored and turned a quarter", 6: "turned a quarter clockwise to view",
                7: "mirrored and turned a quarter", 8: "turned a quarter anticlockwise to view"}
#: Orientations that turn the picture a quarter: the displayed width is the stored height.
_QUARTER_TURNS = frozenset({5, 6, 7, 8})
#: For each orientation, the view of the displayed array in which pixel (row, column) is the stored
#: photo's (row, column): writing the stored rows into it turns them as the camera meant (the
#: inverse of Pillow's ImageOps.exif_transpose, whose results the tests compare).
_STORED_VIEW: dict[int, Callable[[NDArray[np.uint8]], NDArray[np.uint8]]] = {
    1: lambda a: a,
    2: lambda a: a[:, ::-1],
    3: lambda a: a[::-1, ::-1],
    4: lambda a: a[::-1],
    5: lambda a: a.transpose(1, 0, 2),
    6: lambda a: a.transpose(1, 0, 2)[::-1],
    7: lambda a: a.transpose(1, 0, 2)[::-1, ::-1],
    8: lambda a: a.transpose(1, 0, 2)[:, ::-1],
}


def is_raw(path: str | os.PathLike[str]) -> bool:
    """Whether the file is a camera RAW file (by its name's ending, as cameras name them)."""
    return Path(path).suffix.lower() in RAW_SUFFIXES


def image_size(image: Path, file: Any, where: str) -> tuple[int, int]:
    """A photo's size as displayed: (width, height) with its EXIF orientation applied, a RAW file's
    as LibRaw develops it. The image is decoded whole (a RAW file is unpacked), so that a damaged
    or truncated file, or one whose pixel format vebuild refuses (:mod:`.pixels`), is refused now
    rather than when a later stage reads its pixels."""
    if not image.is_file():
        raise ProjectError(file, where, f"photo file not found: {image}")
    if is_raw(image):
        with _open_raw(image, file, where, str(image)) as raw:
            return _raw_size(raw)
    with open_image(image, file, where, decode=True) as img:
        with open(image, "rb") as f:
            head = f.read(_HEAD)
        check_pixel_format(img, file, where, str(image), head=head)
        w, h = img.size
        return (h, w) if photo_orientation(img, file, where, str(image)) in _QUARTER_TURNS else (w, h)


#: The folder (in :func:`vebuild.resources.cache_dir`) where the size of each photo decoded whole
#: is recorded under its SHA-256: the same bytes decoded whole once by the same decoder are known
#: whole, and a command need not decode them again to say so (a house's hundred 24 MP photos were
#: most of every command's start).
DECODED_FOLDER = "photos-decoded"
#: The edition of the rules by which a decoded photo is checked (:mod:`.pixels`), part of the
#: decoder a record names: a photo recorded whole under older rules is decoded and checked again.
PIXEL_RULES = 2


def decoded_size(image: Path, sha256: str, file: Any, where: str) -> tuple[int, int]:
    """:func:`image_size` of a photo whose bytes the caller has checked to have SHA-256 ``sha256``:
    the size recorded when those bytes were last decoded whole on this machine by this decoder,
    else decoded whole now (and recorded; a cache that cannot be written is left alone)."""
    decoder = _decoder(image)
    record = cache_dir() / DECODED_FOLDER / f"{sha256}.json"
    with contextlib.suppress(OSError, ValueError, KeyError, TypeError):  # no record, or not one of ours
        got = json.loads(record.read_text("utf-8"))
        w, h = got["width"], got["height"]
        if got["decoder"] == decoder and type(w) is int and type(h) is int and w > 0 and h > 0:
            return w, h
    size = image_size(image, file, where)
    with contextlib.suppress(OSError):
        record.parent.mkdir(parents=True, exist_ok=True)
        write_text(record, json.dumps({"width": size[0], "height": size[1], "decoder": decoder}))
    return size


def _decoder(image: Path) -> str:
    if is_raw(image):
        import importlib.metadata  # only here: it costs a command 20 ms of start-up

        return f"LibRaw (rawpy {importlib.metadata.version('rawpy')})"
    return f"Pillow {PIL.__version__}, pixel formats {PIXEL_RULES}"


def photo_orientation(img: Image.Image, file: Any, where: str, shown: str) -> int:
    """EXIF orientation (tag 274) of an opened image: 1 (upright) where it has none.

    Raises ProjectError where it is outside 1–8: vebuild does not guess which way up a photo is.
    An EXIF block Pillow cannot parse gives 1, as every viewer shows such a photo.
    """
    try:
        value = img.getexif().get(_ORIENTATION)
    except Exception:  # noqa: BLE001 -- a damaged EXIF block: shown as stored, as by every viewer
        return 1
    if value is None:
        return 1
    if isinstance(value, int) and value in ORIENTATIONS:
        return value
    raise ProjectError(file, where, f"the photo {shown} has EXIF orientation (tag 274) {value!r}; expected 1 to "
                       "8 (1 upright, 3 upside down, 6 and 8 turned a quarter, 2, 4, 5 and 7 mirrored): vebuild "
                       "will not guess which way up it is. Write the right orientation into a copy of the photo "
                       "(e.g. `exiftool -n -Orientation=1 copy.jpg`) and add that copy")


def decode_photo(data: bytes, name: str | os.PathLike[str], file: Any, where: str,
                 label: str | None = None, max_pixels: int | None = None) -> NDArray[np.uint8]:
    """A photo's bytes → its pixels as displayed, (h, w, 3) uint8 RGB: the one decoder of photos.

    Parameters
    ----------
    data : the file's bytes (the bytes that were hashed).
    name : the file's name (a RAW file is told by its ending, :data:`RAW_SUFFIXES`).
    file, where : the project file and JSON path named by errors.
    label : how the photo is named in messages (default ``name``).

    A JPEG, PNG or TIFF is decoded by Pillow, its pixel format turned into 8-bit RGB
    (:func:`.pixels.rgb_image`: 16-bit grey scaled, alpha dropped where every pixel is opaque,
    CMYK, YCbCr, L*a*b* and HSV converted) and turned by its EXIF orientation while it is copied,
    band of rows by band, into the one array returned (no second copy of the whole photo); a RAW
    file is developed by LibRaw (camera white balance, 8 bits, turned by its orientation).

    Raises
    ------
    ProjectError naming ``file`` and ``where``: not an image, damaged, truncated, too large, a
    pixel format vebuild refuses (floating point, 32-bit integers, any pixel not opaque), an
    orientation outside 1–8, or a RAW file LibRaw cannot develop.
    """
    shown = label or str(name)
    limit = MAX_IMAGE_PIXELS if max_pixels is None else max_pixels
    if is_raw(name):
        with _open_raw(io.BytesIO(data), file, where, shown, limit) as raw:
            return _develop(raw, file, where, shown)
    with open_image(io.BytesIO(data), file, where, decode=False, max_pixels=limit, label=shown) as img:
        orientation = photo_orientation(img, file, where, shown)
        try:
            img.load()
            img = rgb_image(img, file, where, shown, head=data[:_HEAD])
            w, h = img.size
            shape = (w, h, 3) if orientation in _QUARTER_TURNS else (h, w, 3)
            out = np.empty(shape, np.uint8)
            stored = _STORED_VIEW[orientation](out)  # (h, w, 3) view: stored row y is stored[y]
            band = max(1, DECODE_BAND_PIXELS // max(1, w))
            for y0 in range(0, h, band):
                stored[y0:y0 + band] = np.asarray(img.crop((0, y0, w, min(h, y0 + band))))
            return out
        except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as e:
            raise ProjectError(file, where, f"cannot decode {shown} as an image: {e}") from None


class _LibRawOutput:
    """What LibRaw writes to the process's standard error (C's, not Python's: "unknown file:
    Unexpected end of file") while it reads a file: kept out of the terminal, where it would stand
    beside vebuild's own message, and quoted in that message instead. When LibRaw succeeds,
    anything written meanwhile is passed on to standard error afterwards."""

    def __init__(self) -> None:
        self.text = ""

    @contextlib.contextmanager
    def captured(self) -> Iterator[None]:
        import sys
        import tempfile

        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError):  # no file descriptor 2 (an embedded interpreter): nothing to keep out
            yield
            return
        with tempfile.TemporaryFile() as sink:
            os.dup2(sink.fileno(), 2)
            try:
                yield
            finally:
                os.dup2(saved, 2)
                os.close(saved)
                sink.seek(0)
                self.text += sink.read().decode("utf-8", "replace")

    def said(self) -> str:
        """LibRaw's lines, as ``" (its own words: …)"``, or "" when it wrote none."""
        lines = [ln.strip() for ln in self.text.splitlines() if ln.strip()]
        return f" (its own words: {'; '.join(lines)})" if lines else ""

    def pass_on(self) -> None:
        if self.text:
            os.write(2, self.text.encode("utf-8"))
            self.text = ""


@contextlib.contextmanager
def _open_raw(source: Path | io.BytesIO, file: Any, where: str, shown: str,
              max_pixels: int = MAX_IMAGE_PIXELS) -> Iterator[Any]:
    """A RAW file opened and unpacked by LibRaw, its size bounded before it is developed."""
    import rawpy

    out = _LibRawOutput()
    try:
        with out.captured():
            raw = rawpy.imread(source if isinstance(source, io.BytesIO) else str(source))
            try:
                raw.unpack()  # reads the raw data: a truncated file fails here, before any development
            except BaseException:
                raw.close()
                raise
    except FileNotFoundError:
        raise ProjectError(file, where, f"photo file not found: {shown}") from None
    except (rawpy.LibRawError, OSError, ValueError) as e:
        raise ProjectError(file, where, f"cannot read {shown} as a camera RAW file: LibRaw {_libraw_version()} says "
                           f"{_libraw_text(e)}{out.said()} (is it a RAW file of a camera LibRaw supports, and "
                           "whole?)") from None
    out.pass_on()
    with raw:
        w, h = _raw_size(raw)
        if w * h > max_pixels:
            raise ProjectError(file, where, f"the image {shown} is {w}×{h} = {w * h / 1e6:.4g} megapixels, more than "
                               f"the {max_pixels / 1e6:g} megapixels vebuild reads (refused before developing it)")
        yield raw


def _raw_size(raw: Any) -> tuple[int, int]:
    """(width, height) LibRaw's development gives: its image turned by its flip (5 and 6 are the
    quarter turns in LibRaw's numbering)."""
    s = raw.sizes
    w, h = int(s.iwidth), int(s.iheight)
    if s.pixel_aspect and abs(s.pixel_aspect - 1.0) > 1e-6:  # LibRaw stretches non-square pixels
        if s.pixel_aspect < 1:
            h = int(h / s.pixel_aspect + 0.5)
        else:
            w = int(w * s.pixel_aspect + 0.5)
    return (h, w) if s.flip in (5, 6) else (w, h)


def _develop(raw: Any, file: Any, where: str, shown: str) -> NDArray[np.uint8]:
    import rawpy

    out = _LibRawOutput()
    try:
        # Camera white balance and LibRaw's default development, 8 bits per channel: what the
        # photographer saw; the geometry (and so every mark) does not depend on these choices.
        with out.captured():
            pixels = np.ascontiguousarray(raw.postprocess(output_bps=8, use_camera_wb=True))
    except (rawpy.LibRawError, OSError, ValueError, MemoryError) as e:
        raise ProjectError(file, where, f"cannot develop the RAW file {shown}: LibRaw says {_libraw_text(e)}"
                           f"{out.said()} (the file may be damaged or truncated)") from None
    out.pass_on()
    if pixels.ndim == 3 and pixels.shape[2] == 1 and pixels.dtype == np.uint8:
        # A monochrome sensor's file (no colour filter): LibRaw develops one channel; grey, r = g = b.
        return np.repeat(pixels, 3, axis=2)
    if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.dtype != np.uint8:
        raise ProjectError(file, where, f"the RAW file {shown} develops to {pixels.dtype} pixels of shape "
                           f"{pixels.shape}; expected 8-bit grey or RGB (h, w, 1 or 3): convert it to DNG or TIFF "
                           "with the camera maker's software and add that copy")
    return pixels


def _libraw_version() -> str:
    import rawpy

    return ".".join(str(v) for v in rawpy.libraw_version)


def _libraw_text(e: BaseException) -> str:
    text = str(e).strip() or type(e).__name__
    return text.removeprefix("b'").removesuffix("'")


def read_exif(path: str | os.PathLike[str]) -> dict[str, Any]:
    """What the camera recorded about a photo: its camera, lens, focal length and orientation.

    Returns
    -------
    dict with the keys of FORMAT.md's ``exif`` object that the file gives (``{}`` for none):
    make, model, body_serial, lens_make, lens_model, orientation (1–8), focal_length_mm and the step it was
    written to (focal_length_mm_step, from the rational's denominator), focal_length_35mm,
    focal_plane_x_resolution_per_mm (along the sensor's x axis, whatever the orientation),
    pixel_x_dimension and pixel_y_dimension (the image's size as the camera wrote it), and the
    derived focal_length_px: the value of :func:`vebuild.calibration.exif.focal_prior` (the
    focal-plane resolution, else the sensor database, else the 35 mm equivalent), in pixels of the
    photo as displayed. EXIF is advisory: a damaged block gives what could be read.
    """
    from vebuild.calibration.exif import focal_prior

    if is_raw(path):
        out, size = _raw_exif(Path(path))
    else:
        out, size = _pillow_exif(Path(path))
    if size is not None and (prior := focal_prior(out, *size)) is not None and 1.0 <= prior.value <= _MAX_FOCAL_PX:
        out["focal_length_px"] = prior.value
    return out


# EXIF tags (EXIF 2.3): Make, Model and Orientation in IFD0; the rest in the Exif IFD.
_MAKE, _MODEL, _EXIF_IFD = 0x010F, 0x0110, 0x8769
_FOCAL_LENGTH, _FOCAL_35MM, _FOCAL_PLANE_XRES, _FOCAL_PLANE_UNIT = 37386, 41989, 41486, 41488
_LENS_MAKE, _LENS_MODEL = 0xA433, 0xA434
_BODY_SERIAL = 0xA431
_PIXEL_X_DIMENSION, _PIXEL_Y_DIMENSION = 0xA002, 0xA003
#: The largest focal length in pixels the format holds (FORMAT.md, "Bounds").
_MAX_FOCAL_PX = 1e7
#: FocalPlaneResolutionUnit → millimetres per unit (2 inch, the default, 3 cm, 4 mm, 5 µm).
_MM_PER_UNIT = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}


def _pillow_exif(path: Path) -> tuple[dict[str, Any], tuple[int, int] | None]:
    with Image.open(path) as img:
        width, height = img.size
        try:
            exif = img.getexif()
            sub = exif.get_ifd(_EXIF_IFD)
        except Exception:  # noqa: BLE001 -- EXIF is advisory: a damaged block must not stop the photo
            return {}, None
    values = {"make": exif.get(_MAKE), "model": exif.get(_MODEL), "orientation": exif.get(_ORIENTATION),
              "lens_make": sub.get(_LENS_MAKE), "lens_model": sub.get(_LENS_MODEL),
              "body_serial": sub.get(_BODY_SERIAL),
              "focal_length_mm": sub.get(_FOCAL_LENGTH), "focal_length_35mm": sub.get(_FOCAL_35MM),
              "resolution": sub.get(_FOCAL_PLANE_XRES), "unit": sub.get(_FOCAL_PLANE_UNIT, 2),
              "pixel_x_dimension": sub.get(_PIXEL_X_DIMENSION), "pixel_y_dimension": sub.get(_PIXEL_Y_DIMENSION)}
    out = _record(values)
    turned = out.get("orientation") in _QUARTER_TURNS
    return out, ((height, width) if turned else (width, height))


def _raw_exif(path: Path) -> tuple[dict[str, Any], tuple[int, int] | None]:
    """A RAW file's EXIF through exifread (RAW files keep EXIF in IFD0, an Exif IFD or both), and
    its size as LibRaw develops it."""
    import exifread

    try:
        with open(path, "rb") as f:
            tags = exifread.process_file(f, details=False)
    except Exception:  # noqa: BLE001 -- EXIF is advisory (exifread raises many kinds on odd files)
        tags = {}

    def tag(name: str) -> Any:
        for group in ("EXIF", "Image"):
            if (t := tags.get(f"{group} {name}")) is not None:
                values = t.values
                if isinstance(values, list | tuple):
                    return values[0] if len(values) == 1 else None
                return values
        return None

    values = {"make": tag("Make"), "model": tag("Model"), "orientation": tag("Orientation"),
              "lens_make": tag("LensMake"), "lens_model": tag("LensModel"), "body_serial": tag("BodySerialNumber"),
              "focal_length_mm": tag("FocalLength"), "focal_length_35mm": tag("FocalLengthIn35mmFilm"),
              "resolution": tag("FocalPlaneXResolution"), "unit": tag("FocalPlaneResolutionUnit") or 2,
              "pixel_x_dimension": tag("ExifImageWidth"), "pixel_y_dimension": tag("ExifImageLength")}
    out = _record(values)
    try:
        with _open_raw(path, path, "", str(path)) as raw:
            size: tuple[int, int] | None = _raw_size(raw)
    except ProjectError:
        size = None
    return out, size


def _record(values: dict[str, Any]) -> dict[str, Any]:
    """The ``exif`` record (FORMAT.md) of the raw tag values, in its key order."""
    out: dict[str, Any] = {}
    for key in ("make", "model", "body_serial", "lens_make", "lens_model"):
        if text := _text(values[key]):
            out[key] = text
    if isinstance(values["orientation"], int) and values["orientation"] in ORIENTATIONS:
        out["orientation"] = values["orientation"]
    # EXIF writes 0 for "unknown"; only positive values are kept, and only within the format's
    # bounds (FORMAT.md: no lens is longer, no pixel smaller), so that no camera's odd value
    # makes the photo's entry invalid.
    if (f_mm := _positive(values["focal_length_mm"])) is not None and f_mm <= 10_000:
        out["focal_length_mm"] = f_mm
        if (step := _decimal_step(values["focal_length_mm"])) is not None:
            out["focal_length_mm_step"] = step
    if (f_35 := _positive(values["focal_length_35mm"])) is not None and f_35 <= 100_000:
        out["focal_length_35mm"] = f_35
    res = _positive(values["resolution"])
    mm_per_unit = _MM_PER_UNIT.get(values["unit"]) if isinstance(values["unit"], int) else None
    if res is not None and mm_per_unit is not None and res / mm_per_unit <= 100_000:
        out["focal_plane_x_resolution_per_mm"] = res / mm_per_unit
    for key in ("pixel_x_dimension", "pixel_y_dimension"):  # the image's size as the camera wrote it
        if isinstance(values[key], int) and 0 < values[key] <= 1_000_000:
            out[key] = values[key]
    return out


def _decimal_step(value: Any) -> float | None:
    """The step an EXIF rational was rounded to, as Pillow read it (numerator and denominator as
    written): 1/denominator where that is a power of ten (180/10: 0.1 mm), 0 where it is not (an
    exact fraction, as software writes: 81/40), None for a value without its denominator."""
    from PIL import TiffImagePlugin  # loaded by Pillow with the EXIF this reads; not at start-up

    den = getattr(value, "denominator", None)
    if not isinstance(value, TiffImagePlugin.IFDRational) or not isinstance(den, int) or den <= 0:
        return None
    power = den
    while power % 10 == 0:
        power //= 10
    return 1.0 / den if power == 1 else 0.0


def _positive(value: Any) -> float | None:
    try:
        x = float(value)  # IFDRational, exifread's Ratio and int alike; a 0/0 rational gives nan
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return x if math.isfinite(x) and x > 0 else None


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return value.strip("\x00 ") if isinstance(value, str) else ""
