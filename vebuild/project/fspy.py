"""Reading fSpy project files (``.fspy``): the header, the saved state, the embedded image (layer 3).

fSpy (https://fspy.io, github.com/stuffmatic/fSpy) saves a project as one binary file, described in
its ``project_file_format.md`` and written by its ``src/gui/io/project-file.ts``:

====== ============================= ==============================================================
offset size                          content
====== ============================= ==============================================================
0      4 bytes                       ``f s p y`` (0x66 0x73 0x70 0x79)
4      uint32, little-endian         the project file version, ``1``
8      uint32, little-endian         S, the size in bytes of the state JSON
12     uint32, little-endian         I, the size in bytes of the image (may be 0: no image)
16     S bytes                       the state, JSON (UTF-8)
16 + S I bytes                       the image file's bytes as loaded (JPEG, PNG, ...)
====== ============================= ==============================================================

The state (fSpy's ``SavedState``) holds ``globalSettings`` (``calibrationMode``:
``OneVanishingPoint`` or ``TwoVanishingPoints``), ``calibrationSettingsBase``,
``calibrationSettings1VP``, ``calibrationSettings2VP``, ``controlPointsStateBase``,
``controlPointsState1VP``, ``controlPointsState2VP``, ``cameraParameters`` (the solver's result, or
null; absent, as is ``resultDisplaySettings``, in files of fSpy before 1.0.0-alpha.5) and
``resultDisplaySettings``; the layouts of fSpy's releases that differ (a pair of control points
saved as an object, a preset without its sensor size) are read as
:mod:`vebuild.project.fspy_state` says. Control points are in fSpy's *relative* image coordinates:
x = 0 and 1 at the left and right edges, y = 0 and 1 at the top and bottom edges (y down), for
portrait and landscape images alike; :func:`relative_to_pixels` turns them into vebuild's pixels.
The solver's result uses fSpy's *image plane* coordinates instead: origin at the image centre, y
up, one unit = half the image's **longer** side (:func:`image_plane_to_pixels`).

This module only parses and checks: every field the import uses is checked for its type and range,
and a fault is a :class:`~vebuild.errors.ProjectError` naming the file and the JSON path of the
field (``$.calibrationSettingsBase.firstVanishingPointAxis``). No calibration happens here
(:mod:`vebuild.actions.fspy` does that).
"""

from __future__ import annotations

import io
import json
import math
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image, UnidentifiedImageError

from vebuild.errors import ProjectError

from .fspy_state import Point, Segment, StateReader, kind
from .images import MAX_IMAGE_PIXELS, sha256_bytes

Array = NDArray[np.float64]

MAGIC = b"fspy"
#: The only project file version fSpy has written (``ProjectFile.PROJECT_FILE_VERSION``).
VERSION = 1
HEADER_SIZE = 16
#: A state larger than this is not an fSpy state (fSpy's are a few kilobytes).
MAX_STATE_BYTES = 16 << 20

MODE_1VP = "OneVanishingPoint"
MODE_2VP = "TwoVanishingPoints"
MODES = (MODE_1VP, MODE_2VP)
#: fSpy's axis names (``Axis`` in src/gui/types/calibration-settings.ts) → (vebuild axis, sign).
AXES: dict[str, tuple[str, int]] = {
    "xPositive": ("x", 1), "xNegative": ("x", -1),
    "yPositive": ("y", 1), "yNegative": ("y", -1),
    "zPositive": ("z", 1), "zNegative": ("z", -1),
}
PRINCIPAL_POINT_MODES_1VP = ("Default", "Manual")
PRINCIPAL_POINT_MODES_2VP = ("Default", "Manual", "FromThirdVanishingPoint")
#: fSpy's reference distance units (``ReferenceDistanceUnit``) → metres; ``No unit`` has none.
UNITS_M: dict[str, float | None] = {
    "No unit": None, "Millimeters": 0.001, "Centimeters": 0.01, "Meters": 1.0, "Kilometers": 1000.0,
    "Inches": 0.0254, "Feet": 0.3048, "Miles": 1609.344,
    "Yards": 0.9144,  # written by early fSpy versions (fSpy itself converts them to feet on loading)
}
#: The field of view across the image's longer side that a one-vanishing-point project's lens and
#: sensor may give, degrees: from a 3400 mm lens to a fisheye's, on a full-frame sensor.
FOV_1VP_DEG = (0.6, 178.0)
#: The same as fSpy's relative focal length (2F / the sensor's longer side = 1 / tan(FOV / 2)).
REL_FOCAL_1VP = (1.0 / math.tan(math.radians(FOV_1VP_DEG[1] / 2)), 1.0 / math.tan(math.radians(FOV_1VP_DEG[0] / 2)))
#: Image formats vebuild keeps as photos (FORMAT.md, "Photo object") → the file ending written.
IMAGE_ENDINGS = {"JPEG": ".jpg", "PNG": ".png", "TIFF": ".tif"}


@dataclass(frozen=True)
class FspyCamera:
    """fSpy's stored solver result (``cameraParameters``), as fSpy wrote it.

    principal_point : image plane coordinates (see the module's docstring).
    view_transform : 4×4, world → fSpy's camera (OpenGL: x right, y up, looking along −z); the
        translation is in the reference distance's unit, or arbitrary (the origin 10 units in front
        of the camera) where no reference distance was set.
    camera_transform : its inverse, as stored.
    horizontal_fov_rad, vertical_fov_rad : as stored. fSpy computes the "horizontal" one over the
        image's **longer** side (2 atan(1 / relative focal length)), so for a portrait image it is the
        vertical field of view.
    vanishing_points : three, image plane coordinates; ``vanishing_point_axes`` their axes.
    relative_focal_length : the focal length in units of half the longer side.
    """

    principal_point: Point
    view_transform: Array
    camera_transform: Array
    horizontal_fov_rad: float
    vertical_fov_rad: float
    vanishing_points: tuple[Point, Point, Point]
    vanishing_point_axes: tuple[str, str, str]
    relative_focal_length: float
    image_width: float
    image_height: float


@dataclass(frozen=True)
class FspyProject:
    """What the import uses from one ``.fspy`` file; coordinates are fSpy's relative ones."""

    path: Path
    version: int
    state: dict[str, Any]
    image: bytes
    image_sha256: str
    image_format: str
    width: int
    height: int
    mode: str
    first_axis: str
    second_axis: str
    principal_point_mode: str
    quad_mode: bool
    first_segments: tuple[Segment, Segment]
    second_segments: tuple[Segment, Segment] | None
    third_segments: tuple[Segment, Segment] | None
    horizon: Segment | None
    principal_point: Point
    origin: Point
    reference_axis: str | None
    reference_distance: float
    reference_unit: str
    reference_anchor: Point
    reference_offsets: tuple[float, float]
    focal_length_mm: float | None
    sensor_mm: tuple[float, float] | None
    sensor_source: str
    camera: FspyCamera | None

    @property
    def third_axis(self) -> str:
        """fSpy's third axis: the first axis × the second (``computeCameraParameters``)."""
        return cross_axis(self.first_axis, self.second_axis)

    @property
    def image_ending(self) -> str:
        return IMAGE_ENDINGS[self.image_format]


def axis_vector(name: str) -> Array:
    letter, sign = AXES[name]
    v = np.zeros(3)
    v["xyz".index(letter)] = sign
    return v


def cross_axis(first: str, second: str) -> str:
    v = np.cross(axis_vector(first), axis_vector(second))
    i = int(np.argmax(np.abs(v)))
    return f"{'xyz'[i]}{'Positive' if v[i] > 0 else 'Negative'}"


def relative_to_pixels(p: Point, width: int, height: int) -> Array:
    """fSpy's relative coordinates → vebuild's pixels: x·w, y·h (both measure from the top-left
    corner of the image, y down; fSpy's ``relativeToAbsolute``)."""
    return np.array([p[0] * width, p[1] * height], float)


def image_plane_scale(width: float, height: float) -> float:
    """Pixels per unit of fSpy's image plane: half the longer side."""
    return max(width, height) / 2.0


def image_plane_to_pixels(p: Point, width: float, height: float) -> Array:
    """fSpy's image plane (origin at the centre, y up, unit = half the longer side) → pixels."""
    s = image_plane_scale(width, height)
    return np.array([width / 2.0 + p[0] * s, height / 2.0 - p[1] * s], float)


# --------------------------------------------------------------------------------------------------
# Reading


def read_fspy(path: str | Path) -> FspyProject:
    """Read and check an fSpy project file.

    Raises
    ------
    ProjectError : naming the file and the field: not an fSpy file, a truncated file, another
        version, a state that is not JSON or lacks a field the import needs, an image whose size
        disagrees with the header or that cannot be decoded.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ProjectError(path, "", "fSpy project file not found") from None
    except IsADirectoryError:
        raise ProjectError(path, "", "is a folder; expected an fSpy project file (.fspy)") from None
    except OSError as e:
        raise ProjectError(path, "", f"cannot read the fSpy project file: {e.strerror or e}") from None
    return parse_fspy(data, path)


def parse_fspy(data: bytes, path: Path) -> FspyProject:
    """:func:`read_fspy` over bytes already read (``path`` names them in messages)."""
    if len(data) < 4 or data[:4] != MAGIC:
        found = data[:4].hex(" ") if data else "an empty file"
        raise ProjectError(path, "header", f"not an fSpy project file: expected the 4 bytes 'fspy' (66 73 70 79) "
                           f"at its start, found {found}")
    if len(data) < HEADER_SIZE:
        raise ProjectError(path, "header", f"truncated: the header is {HEADER_SIZE} bytes, the file has only "
                           f"{len(data)}")
    version, state_size, image_size = struct.unpack_from("<III", data, 4)
    if version != VERSION:
        raise ProjectError(path, "header.project_file_version", f"fSpy project file version {version}; vebuild "
                           f"reads version {VERSION} (the only one fSpy writes)")
    if state_size == 0 or state_size > MAX_STATE_BYTES:
        raise ProjectError(path, "header.state_size", f"expected a state of 1 byte to {MAX_STATE_BYTES >> 20} MiB, "
                           f"the header says {state_size} bytes")
    if image_size == 0:
        raise ProjectError(path, "header.image_size", "the project holds no image (image size 0); vebuild needs the "
                           "photo: load the image in fSpy and save the project again")
    expected = HEADER_SIZE + state_size + image_size
    if len(data) < expected:
        raise ProjectError(path, "header.image_size", f"truncated: the header says {state_size} bytes of state and "
                           f"{image_size} of image ({expected} bytes in all), the file has only {len(data)}: expected "
                           "the whole file fSpy wrote")
    if len(data) > expected:
        raise ProjectError(path, "header.image_size", f"the header says {state_size} bytes of state and {image_size} "
                           f"of image ({expected} bytes in all), but the file has {len(data)}: {len(data) - expected} "
                           "bytes more; it is not a file fSpy wrote whole")
    raw_state = data[HEADER_SIZE:HEADER_SIZE + state_size]
    image = data[HEADER_SIZE + state_size:]
    try:
        state = json.loads(raw_state.decode("utf-8"), parse_constant=_no_constant)
    except UnicodeDecodeError as e:
        raise ProjectError(path, "state", f"the state is not UTF-8 text (byte {e.start} cannot be read)") from None
    except (ValueError, RecursionError) as e:
        raise ProjectError(path, "state", f"the state is not valid JSON ({e})") from None
    if not isinstance(state, dict):
        raise ProjectError(path, "$", f"expected the state to be a JSON object, found {kind(state)}")
    fmt, width, height = _image_facts(image, path)
    return _State(path, state).project(version, image, fmt, width, height)


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _image_facts(image: bytes, path: Path) -> tuple[str, int, int]:
    where = "image"
    try:
        with Image.open(io.BytesIO(image)) as img:
            fmt = str(img.format)
            width, height = img.size
            if width * height > MAX_IMAGE_PIXELS:
                raise ProjectError(path, where, f"the image has {width * height / 1e6:.0f} megapixels, more than "
                                   f"vebuild reads ({MAX_IMAGE_PIXELS / 1e6:g})")
            if fmt not in IMAGE_ENDINGS:
                raise ProjectError(path, where, f"the embedded image is {fmt}; vebuild keeps JPEG, PNG or TIFF "
                                   "photos: convert the image, load it in fSpy again and save the project")
            from .images import photo_orientation

            orientation = photo_orientation(img, path, where, "the embedded image")
            img.load()
            from .pixels import check_pixel_format

            check_pixel_format(img, path, where, "image", noun="embedded", head=image[:32])
    except ProjectError:
        raise
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError, Image.DecompressionBombError) as e:
        raise ProjectError(path, where, f"the embedded image cannot be decoded: it is not an image, or damaged or "
                           f"truncated ({e})") from None
    if orientation in (5, 6, 7, 8):  # shown turned a quarter: the size as displayed (FORMAT.md)
        width, height = height, width
    return fmt, width, height


class _State(StateReader):
    """The state as the import uses it (:class:`~vebuild.project.fspy_state.StateReader`)."""

    # -- the whole project ----------------------------------------------------------------------

    def project(self, version: int, image: bytes, fmt: str, width: int, height: int) -> FspyProject:
        mode = self.choice("$.globalSettings.calibrationMode", MODES)
        first = self.choice("$.calibrationSettingsBase.firstVanishingPointAxis", AXES)
        second = self.choice("$.calibrationSettingsBase.secondVanishingPointAxis", AXES)
        assert mode is not None and first is not None and second is not None
        if AXES[first][0] == AXES[second][0]:
            raise self.error("$.calibrationSettingsBase.secondVanishingPointAxis",
                             f"expected an axis other than the first vanishing point's ({first!r}), found {second!r}")
        one = mode == MODE_1VP
        pp_mode = self.choice(f"$.calibrationSettings{'1VP' if one else '2VP'}.principalPointMode",
                              PRINCIPAL_POINT_MODES_1VP if one else PRINCIPAL_POINT_MODES_2VP)
        assert pp_mode is not None
        quad = False
        if not one:
            # Absent in files from before fSpy had a quad mode; fSpy then reads it as off.
            q = self.get("$.calibrationSettings2VP.quadModeEnabled", optional=True)
            q = False if q is None else q
            if not isinstance(q, bool):
                raise self.error("$.calibrationSettings2VP.quadModeEnabled",
                                 f"expected true or false, found {kind(q)}")
            quad = q
        first_segs = self.segments("$.controlPointsStateBase.firstVanishingPoint")
        second_segs = third_segs = None
        horizon = None
        if one:
            if self.get("$.controlPointsState1VP.horizon", optional=True) is None:
                raise self.error("$.controlPointsState1VP.horizon", "missing: a one-vanishing-point project needs its "
                                 "horizon (two control points), which sets the camera's roll; open the project in "
                                 "fSpy, place the horizon and save it again")
            horizon = self.pair("$.controlPointsState1VP.horizon")
        elif quad:
            a, b = first_segs  # fSpy's quad: the second vanishing point from the corners' other pairing
            second_segs = ((a[0], b[0]), (a[1], b[1]))
        else:
            second_segs = self.segments("$.controlPointsState2VP.secondVanishingPoint")
        if not one and pp_mode == "FromThirdVanishingPoint":
            third_segs = self.segments("$.controlPointsState2VP.thirdVanishingPoint")
        pp = self.point("$.controlPointsStateBase.principalPoint") if pp_mode == "Manual" else (0.5, 0.5)
        origin = self.point("$.controlPointsStateBase.origin")
        ref_axis = self.choice("$.calibrationSettingsBase.referenceDistanceAxis", AXES, optional=True)
        ref_distance, ref_unit = 0.0, "No unit"
        anchor: Point = origin
        offsets = (0.0, 0.0)
        if ref_axis is not None:
            if AXES[ref_axis][1] < 0:
                raise self.error("$.calibrationSettingsBase.referenceDistanceAxis",
                                 "expected xPositive, yPositive or zPositive (fSpy offers only those), "
                                 f"found {ref_axis!r}")
            ref_distance = self.number("$.calibrationSettingsBase.referenceDistance", lo=1e-12,
                                       what="a reference distance above 0")
            unit = self.choice("$.calibrationSettingsBase.referenceDistanceUnit", UNITS_M)
            assert unit is not None
            ref_unit = unit
            anchor = self.point("$.controlPointsStateBase.referenceDistanceAnchor")
            offs = self.get("$.controlPointsStateBase.referenceDistanceHandleOffsets")
            where = "$.controlPointsStateBase.referenceDistanceHandleOffsets"
            if not isinstance(offs, list) or len(offs) != 2:
                raise self.error(where, f"expected two numbers, found {kind(offs)}")
            offsets = (self.number(f"{where}[0]", lo=-10, hi=10), self.number(f"{where}[1]", lo=-10, hi=10))
            if abs(offsets[0] - offsets[1]) < 1e-9:
                raise self.error(where, "expected two different offsets: the two handles of the reference "
                                 "distance lie on one point")
        focal_mm = None
        sensor = None
        sensor_source = ""
        if one:
            focal_mm = self.number("$.calibrationSettings1VP.absoluteFocalLength", lo=1e-3, hi=1e5,
                                   what="a focal length in millimetres above 0")
            sensor, sensor_source = self.sensor()
            rel = 2.0 * focal_mm / (sensor[0] if sensor[0] / sensor[1] > 1 else sensor[1])
            if not REL_FOCAL_1VP[0] <= rel <= REL_FOCAL_1VP[1]:
                fov = math.degrees(2.0 * math.atan(1.0 / rel))
                raise self.error("$.calibrationSettings1VP.absoluteFocalLength", f"a {focal_mm:g} mm lens on "
                                 f"{sensor_source} ({sensor[0]:g} × {sensor[1]:g} mm) sees {fov:.3g}° across the "
                                 f"image's longer side; expected {FOV_1VP_DEG[0]:g}° to {FOV_1VP_DEG[1]:g}°: check "
                                 "the focal length and the sensor size")
        camera = self._camera()
        return FspyProject(
            path=self.path, version=version, state=self.state, image=image, image_sha256=sha256_bytes(image),
            image_format=fmt, width=width, height=height, mode=mode, first_axis=first, second_axis=second,
            principal_point_mode=pp_mode, quad_mode=quad, first_segments=first_segs, second_segments=second_segs,
            third_segments=third_segs, horizon=horizon, principal_point=pp, origin=origin, reference_axis=ref_axis,
            reference_distance=ref_distance, reference_unit=ref_unit, reference_anchor=anchor,
            reference_offsets=offsets, focal_length_mm=focal_mm, sensor_mm=sensor, sensor_source=sensor_source,
            camera=camera,
        )

    def _camera(self) -> FspyCamera | None:
        base = "$.cameraParameters"
        cam = self.state.get("cameraParameters")
        if cam is None:
            return None
        if not isinstance(cam, dict):
            raise self.error(base, f"expected an object or null, found {kind(cam)}")
        pp = self.point(f"{base}.principalPoint", relative=False)
        view = self._matrix(f"{base}.viewTransform")
        inverse = self._matrix(f"{base}.cameraTransform")
        R = view[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise self.error(f"{base}.viewTransform", "expected a rotation and a translation, found a matrix whose "
                             "upper-left 3×3 is not a rotation")
        vps = self.get(f"{base}.vanishingPoints")
        if not isinstance(vps, list) or len(vps) != 3:
            raise self.error(f"{base}.vanishingPoints", f"expected three points, found {kind(vps)}")
        points = tuple(self.point(f"{base}.vanishingPoints[{i}]", relative=False) for i in range(3))
        axes = self.get(f"{base}.vanishingPointAxes")
        if not isinstance(axes, list) or len(axes) != 3 or not all(isinstance(a, str) and a in AXES for a in axes) or \
                sorted(AXES[a][0] for a in axes) != ["x", "y", "z"]:
            raise self.error(f"{base}.vanishingPointAxes", f"expected three axis names, one each of x, y and z "
                             f"(such as 'xPositive'), found {kind(axes)}")
        return FspyCamera(
            principal_point=pp, view_transform=view, camera_transform=inverse,
            horizontal_fov_rad=self.number(f"{base}.horizontalFieldOfView", lo=1e-9, hi=math.pi,
                                           what="an angle in radians, 0 to π"),
            vertical_fov_rad=self.number(f"{base}.verticalFieldOfView", lo=1e-9, hi=math.pi,
                                         what="an angle in radians, 0 to π"),
            vanishing_points=(points[0], points[1], points[2]),
            vanishing_point_axes=(str(axes[0]), str(axes[1]), str(axes[2])),
            relative_focal_length=self.number(f"{base}.relativeFocalLength", lo=1e-6, hi=1e6,
                                              what="a relative focal length above 0"),
            image_width=self.number(f"{base}.imageWidth", lo=1, hi=65535, what="an image width in pixels"),
            image_height=self.number(f"{base}.imageHeight", lo=1, hi=65535, what="an image height in pixels"),
        )

    def _matrix(self, where: str) -> Array:
        v = self.get(where)
        rows = v.get("rows") if isinstance(v, dict) else None
        if not (isinstance(rows, list) and len(rows) == 4 and all(isinstance(r, list) and len(r) == 4 for r in rows)):
            raise self.error(f"{where}.rows", "expected a 4×4 matrix {\"rows\": [[4 numbers] × 4]}")
        return np.array([[self.number(f"{where}.rows[{i}][{j}]", lo=-1e12, hi=1e12) for j in range(4)]
                         for i in range(4)])
