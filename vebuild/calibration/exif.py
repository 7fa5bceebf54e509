"""Camera knowledge (layer 2): what EXIF and the packaged databases say about a photo's camera.

Pure functions over a photo's ``exif`` record (scenes/FORMAT.md, read by
:func:`vebuild.project.images.read_exif`) and its size in pixels *as displayed* (EXIF orientation
applied). They give

* :func:`focal_prior`: the EXIF focal length in pixels as a :class:`FocalPrior` whose 1σ says how
  little EXIF knows, and whose ``source`` says how the pixels were found: from the focal-plane
  resolution the camera recorded, else from the sensor width in the database shipped with vebuild
  (``vebuild/data/sensors.csv``) found by make and model, else from the 35 mm equivalent;
* :func:`find_sensor`: that database's entry for a make and model;
* :func:`lens_distortion_prior`: the division model's k1 (vebuild/camera.py) fitted to the lens's
  profile in the lensfun database, where EXIF names the lens and lensfunpy is installed.

The 1σ of the focal prior
-------------------------
EXIF's focal length is nominal. The prior's relative 1σ combines in quadrature

* the rounding of what the camera wrote, a uniform error of one step (1/√12 of it): the step the
  EXIF rational shows (18/1: 1 mm, 180/10: 0.1 mm; none for an exact fraction such as 81/40), or
  where the record does not say (exifread reduces RAW files' rationals), 1 mm for a whole number of
  millimetres, else 0.1 mm, else 0.01 mm; the 35 mm equivalent is whole millimetres by the standard;
* for a 35 mm equivalent, the spread of its definitions: some cameras define it by the diagonal,
  others by the width, which differ on an image not of 3:2 shape (4 % at 4:3): a uniform error
  between the two;
* what EXIF cannot know (``floor_rel``, the project's ``exif_focal_sigma_rel``: 3 % unless the user
  says otherwise, :data:`NOMINAL_FOCAL_SIGMA_REL`): a lens's marked focal length may be 5 % off its
  true one (ISO 517; uniform, 2.9 % 1σ); focusing at 2–5 m lengthens an 18–35 mm lens's image
  distance by 0.4–1.8 %; a zoom reports the step of its position encoder, a fixed-lens camera one
  value whatever the zoom; and the sensor's width, from the focal-plane resolution or the database,
  is nominal (given to 0.1 mm; the active area differs from the image by a few pixels), about 1 %.
  Together about 3 %. On a public set of real photos EXIF was 4.1 % below the calibrated focal
  length: 1.2σ of this prior at 18 mm.
"""

from __future__ import annotations

import csv
import functools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from vebuild.resources import package_data_file

from .priors import DistortionPrior, FocalPrior

#: The diagonal of a 36 × 24 mm frame, that a 35 mm-equivalent focal length refers to.
FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)
FULL_FRAME_WIDTH_MM = 36.0
#: The default 1σ (relative) of what EXIF cannot know about a focal length, the sensor's nominal
#: width included (module docstring); the rounding of what was written is added to it.
NOMINAL_FOCAL_SIGMA_REL = 0.03
#: A sensor width implied by EXIF's focal-plane resolution that differs from the database's by
#: more than this (relative) is taken to be wrong (a resized image, a camera that writes the
#: resolution of another image size): the database is used instead.
FOCAL_PLANE_DISAGREEMENT = 0.05
#: Where the sensor database is, inside the package (see its header for its source and licence).
SENSOR_DATABASE = "sensors.csv"
SENSOR_DATABASE_NAME = "AliceVision cameraSensors.db"

#: Orientations (EXIF tag 274) that turn the picture a quarter: the displayed x axis is the
#: sensor's y axis.
QUARTER_TURNS = frozenset({5, 6, 7, 8})


@dataclass(frozen=True)
class SensorEntry:
    """One camera of the sensor database: the sensor's width (its x axis, mm) and the sources
    the database names for it."""

    make: str
    model: str
    width_mm: float
    sources: str


# --------------------------------------------------------------------------------------------------
# The sensor database


#: Words a maker puts before the model in the database but not (always) in EXIF's Model.
_SERIES = {"panasonic": {"lumix"}, "sony": {"cybershot", "alpha"}, "olympus": {"omd", "pen"}, "nikon": {"1"}}
#: EXIF Make's first word → the maker's name in the database.
_MAKER_ALIASES = {"eastman": "kodak", "om": "olympus", "ricoh": "pentax", "hmd": "nokia", "lge": "lg"}


def _words(text: str) -> list[str]:
    return [w for w in (re.sub(r"[^0-9a-z]", "", t) for t in text.lower().split()) if w]


def _maker(make: str) -> str:
    words = _words(make)
    first = words[0] if words else ""
    return _MAKER_ALIASES.get(first, first)


def _model_key(maker: str, model: str) -> str:
    """The model's words without the maker's name or series word in front, joined: "NIKON D7000"
    and "Nikon D7000" → "d7000"; "Panasonic Lumix DMC-GH4" and "DMC-GH4" → "dmcgh4"."""
    words = _words(model)
    if words and words[0] == maker:
        words = words[1:]
    while len(words) > 1 and words[0] in _SERIES.get(maker, ()):
        words = words[1:]
    return "".join(words)


@functools.cache
def sensor_database() -> tuple[SensorEntry, ...]:
    """Every camera of the packaged sensor database, in file order."""
    with open(package_data_file(SENSOR_DATABASE), encoding="utf-8", newline="") as f:
        rows = [r for r in csv.reader(line for line in f if line.strip() and not line.startswith("#"))]
    return tuple(SensorEntry(r[0].strip(), r[1].strip(), float(r[2]), r[3].strip() if len(r) > 3 else "")
                 for r in rows)


@functools.cache
def _index() -> tuple[dict[tuple[str, str], SensorEntry], dict[str, list[SensorEntry]]]:
    by_maker: dict[tuple[str, str], SensorEntry] = {}
    by_model: dict[str, list[SensorEntry]] = {}
    for e in sensor_database():
        maker = _maker(e.make)
        key = _model_key(maker, e.model)
        by_maker.setdefault((maker, key), e)
        by_model.setdefault(key, []).append(e)
    return by_maker, by_model


def find_sensor(make: str | None, model: str | None) -> SensorEntry | None:
    """The database's entry for a camera as EXIF names it (Make, Model), or None.

    Names are compared without case, punctuation or spaces, without the maker's name repeated in
    front of the model, and without a series word the maker writes in one but not the other
    ("Lumix", "Cyber-shot", "OM-D"); a model found under another maker's name counts only where it
    is the only camera of that name in the database (e.g. RICOH IMAGING for a PENTAX K-1).
    """
    if not model:
        return None
    maker = _maker(make or "")
    key = _model_key(maker, model)
    if not key:
        return None
    by_maker, by_model = _index()
    if (found := by_maker.get((maker, key))) is not None:
        return found
    others = {(e.width_mm, e.make) for e in by_model.get(key, [])}
    if len(others) == 1:
        return by_model[key][0]
    return None


# --------------------------------------------------------------------------------------------------
# The focal length


def sensor_axes_px(exif: Mapping[str, Any], width: int, height: int) -> tuple[int, int]:
    """How many pixels of the photo lie along the sensor's x and y axes: its displayed width and
    height, swapped where EXIF's orientation turned the picture a quarter (5–8)."""
    if exif.get("orientation") in QUARTER_TURNS:
        return height, width
    return width, height


def _step_mm(f_mm: float) -> float:
    """The rounding step of a focal length as cameras write it: whole, tenths or hundredths of mm."""
    for step in (1.0, 0.1):
        if abs(f_mm / step - round(f_mm / step)) < 1e-6:
            return step
    return 0.01


def _focal_step(exif: Mapping[str, Any], f_mm: float) -> float:
    """The step the focal length was written to: the record's ``focal_length_mm_step`` (from the
    EXIF rational's denominator, 0 for an exact fraction) where read, else :func:`_step_mm`."""
    step = exif.get("focal_length_mm_step")
    return float(step) if isinstance(step, int | float) and step >= 0 else _step_mm(f_mm)


def _rounding_rel(value: float, step: float) -> float:
    return step / math.sqrt(12.0) / value


def focal_prior(exif: Mapping[str, Any], width: int, height: int,
                floor_rel: float = NOMINAL_FOCAL_SIGMA_REL) -> FocalPrior | None:
    """The focal length EXIF implies, in pixels of the displayed photo, as a prior; None when EXIF
    gives no focal length that can be put in pixels.

    Parameters
    ----------
    exif : the photo's ``exif`` record (FORMAT.md).
    width, height : the photo's size as displayed (its ``width`` and ``height``).
    floor_rel : the 1σ (relative) of what EXIF cannot know (module docstring).

    The value comes from the first of: the focal length × the photo's pixels along the sensor's x
    axis / the sensor's width from the focal-plane resolution (EXIF's PixelXDimension, else those
    pixels, over the resolution; unless it differs from the database's width by more than
    FOCAL_PLANE_DISAGREEMENT); the same with the database's sensor width; the 35 mm equivalent ×
    the image diagonal / 43.27 mm. ``source`` names which, after "exif: " (the word by which
    calibration and its record tell an EXIF focal length).
    """
    f_mm = _positive(exif.get("focal_length_mm"))
    f_35 = _positive(exif.get("focal_length_35mm"))
    res = _positive(exif.get("focal_plane_x_resolution_per_mm"))
    sx, _ = sensor_axes_px(exif, width, height)
    entry = find_sensor(exif.get("make"), exif.get("model"))
    # The focal-plane resolution is of the image the camera wrote, PixelXDimension wide where EXIF
    # says: a photo resized since keeps the sensor's width, PixelXDimension / resolution.
    sensor_mm = (_positive(exif.get("pixel_x_dimension")) or sx) / res if res is not None else None
    terms = [floor_rel]
    if f_mm is not None and sensor_mm is not None and _agrees(sensor_mm, entry):
        value = f_mm * sx / sensor_mm
        terms.append(_rounding_rel(f_mm, _focal_step(exif, f_mm)))
        source = f"exif: {f_mm:g} mm × focal-plane resolution {res:.5g} px/mm (sensor {sensor_mm:.3g} mm wide)"
    elif f_mm is not None and entry is not None:
        value = f_mm * sx / entry.width_mm
        terms.append(_rounding_rel(f_mm, _focal_step(exif, f_mm)))
        named = f"; {entry.sources}" if entry.sources else ""
        source = (f"exif: {f_mm:g} mm × sensor {entry.width_mm:g} mm (database: {entry.make} {entry.model}, "
                  f"{SENSOR_DATABASE_NAME}{named})")
    elif f_35 is not None:
        diagonal = math.hypot(width, height)
        value = f_35 * diagonal / FULL_FRAME_DIAGONAL_MM
        by_width = f_35 * max(width, height) / FULL_FRAME_WIDTH_MM  # what cameras defining it by width mean
        terms += [_rounding_rel(f_35, 1.0), abs(by_width - value) / value / math.sqrt(12.0)]
        source = f"exif: 35 mm equivalent {f_35:g} mm over the image diagonal"
    else:
        return None
    sigma_rel = math.sqrt(sum(t * t for t in terms))
    return FocalPrior(float(value), float(value * sigma_rel), source)


def exif_focal_prior(photo: Mapping[str, Any], floor_rel: float = NOMINAL_FOCAL_SIGMA_REL) -> FocalPrior | None:
    """:func:`focal_prior` of a photo object (its ``exif``, ``width`` and ``height``)."""
    return focal_prior(photo.get("exif") or {}, int(photo["width"]), int(photo["height"]), floor_rel)


def _agrees(width_mm: float, entry: SensorEntry | None) -> bool:
    """Whether a sensor width from the focal-plane resolution agrees with the database's (where it
    has the camera) to FOCAL_PLANE_DISAGREEMENT."""
    return entry is None or abs(width_mm - entry.width_mm) <= FOCAL_PLANE_DISAGREEMENT * entry.width_mm


def _positive(value: Any) -> float | None:
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) and x > 0 else None


# --------------------------------------------------------------------------------------------------
# The lens profile


#: 1σ (relative) of a k1 from a lens profile: lensfun profiles one copy of the lens focused far
#: away; copies differ, and focusing near changes the distortion by 10–20 %.
LENS_PROFILE_SIGMA_REL = 0.25
#: The least 1σ of a profile's k1, as the displacement it makes at the image corner (pixels).
LENS_PROFILE_SIGMA_MIN_PX = 0.5
#: Samples per image side of the least-squares fit of the division model to the profile.
LENS_FIT_SAMPLES = 41


def lens_distortion_prior(exif: Mapping[str, Any], width: int, height: int, focal_px: float,
                          database: Any = None) -> DistortionPrior | None:
    """The division model's k1 that best matches the lens profile in the lensfun database at the
    photo's focal length, as a prior; None where EXIF names no lens, the lens (or the focal length)
    is not in the database, or lensfunpy is not installed.

    Parameters
    ----------
    exif : the photo's ``exif`` record: ``lens_model`` (and ``lens_make``), ``focal_length_mm``,
        ``make``, ``model`` and ``focal_length_35mm`` for the crop factor.
    width, height : the photo's size as displayed.
    focal_px : the photo's focal length in pixels (the EXIF focal prior's value): k1 is in
        f-normalised coordinates.
    database : a ``lensfunpy.Database`` (default: the one lensfunpy ships, loaded once).

    The fit: lensfun maps each pixel p_u of its corrected image to where the lens put it, p_d.
    In f-normalised radii (ρ = |p − c| / f) the division model says ρ_u = s·ρ_d / (1 + k1 ρ_d²),
    where s lets the corrected image's scale differ from the paraxial one; k1 and s solve the
    linear least squares ρ_u + k1 ρ_u ρ_d² = s ρ_d over a grid of LENS_FIT_SAMPLES² pixels. The 1σ
    is LENS_PROFILE_SIGMA_REL of k1, with the fit's RMS residual and LENS_PROFILE_SIGMA_MIN_PX at
    the corner (as k1) added in quadrature.
    """
    lens_name = exif.get("lens_model")
    f_mm = _positive(exif.get("focal_length_mm"))
    if not lens_name or f_mm is None or not focal_px > 0:
        return None
    try:
        import lensfunpy
    except ImportError:
        return None
    db = database if database is not None else _lensfun_database()
    cams = db.find_cameras(exif.get("make") or None, exif.get("model") or None) if exif.get("model") else []
    crop = cams[0].crop_factor if cams else None
    if not crop and (f_35 := _positive(exif.get("focal_length_35mm"))):
        crop = f_35 / f_mm
    if not crop:
        return None
    lenses = db.find_lenses(cams[0] if cams else None, exif.get("lens_make") or None, str(lens_name))
    lenses = [ln for ln in lenses if ln.calib_distortion and ln.min_focal
              and ln.min_focal - 0.05 <= f_mm <= (ln.max_focal or ln.min_focal) + 0.05]
    if not lenses:
        return None
    lens = lenses[0]
    w, h = int(width), int(height)
    modifier = lensfunpy.Modifier(lens, crop, w, h)
    modifier.initialize(f_mm, lens.min_aperture or 8.0, 1000.0)
    us = np.linspace(0, w - 1, LENS_FIT_SAMPLES).round().astype(int)
    vs = np.linspace(0, h - 1, LENS_FIT_SAMPLES).round().astype(int)
    coords = modifier.apply_geometry_distortion()[np.ix_(vs, us)]  # (n, n, 2): p_d of each p_u
    c = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    pu = np.stack(np.meshgrid(us, vs), axis=-1).astype(float)
    rho_u = np.linalg.norm(pu - c, axis=-1).ravel() / focal_px
    rho_d = np.linalg.norm(coords - c, axis=-1).ravel() / focal_px
    A = np.stack([rho_u * rho_d**2, -rho_d], axis=1)
    (k1, s), *_ = np.linalg.lstsq(A, -rho_u, rcond=None)
    if not (math.isfinite(k1) and s > 0):
        return None
    resid_px = focal_px * (s * rho_d / (1.0 + k1 * rho_d**2) - rho_u)
    rms_px = float(np.sqrt(np.mean(resid_px**2)))
    corner = math.hypot(w, h) / 2.0 / focal_px
    per_k1_px = focal_px * corner**3  # the corner's displacement per unit k1 (to first order)
    sigma = math.sqrt((LENS_PROFILE_SIGMA_REL * k1) ** 2 + (rms_px / per_k1_px) ** 2
                      + (LENS_PROFILE_SIGMA_MIN_PX / per_k1_px) ** 2)
    return DistortionPrior(float(k1), float(sigma), f"lens profile: {lens.maker} {lens.model} at {f_mm:g} mm "
                           f"(lensfun database; division-model fit {rms_px:.2f} px RMS)")


def exif_distortion_prior(photo: Mapping[str, Any], focal_px: float | None = None) -> DistortionPrior | None:
    """:func:`lens_distortion_prior` of a photo object (its ``exif``, ``width`` and ``height``), at
    ``focal_px`` (default: the EXIF focal prior's value; None where EXIF gives no focal length)."""
    exif = photo.get("exif") or {}
    if focal_px is None:
        prior = exif_focal_prior(photo)
        if prior is None:
            return None
        focal_px = prior.value
    return lens_distortion_prior(exif, int(photo["width"]), int(photo["height"]), focal_px)


@functools.cache
def _lensfun_database() -> Any:
    import lensfunpy

    return lensfunpy.Database()
