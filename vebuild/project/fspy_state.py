"""Typed access to an fSpy project's state JSON, every fault named by its JSON path (layer 3).

:mod:`vebuild.project.fspy` reads the file; this module holds what it checks the state's values
with, and what fSpy's own releases write that the reader must accept (github.com/stuffmatic/fSpy,
tags v1.0.0-alpha.1 to 1.1.0-beta.3):

- a pair of control points (``ControlPointPairState`` in ``src/gui/types/control-points-state.ts``)
  is a list of two points, or — once fSpy has changed one of them — an object with the keys "0"
  and "1": fSpy's ``ADJUST_HORIZON`` reducer (``src/gui/reducers/control-points-1-vp.ts``) copies
  the horizon with ``{ ...state.horizon }``, which turns the list into such an object, and saves it
  so. fSpy reads a pair by index (``pair[0]``, ``pair[1]``), which reads both forms, and so does
  vebuild, for every pair;
- the camera presets: a project names one by ``cameraData.presetId``; fSpy before 1.0.0 did not
  save its sensor size (``presetData``), and fSpy's loader (``src/gui/io/project-file.ts``) takes it
  from its table of presets (``src/gui/solver/camera-presets.ts``, unchanged since 1.0.0-alpha.1
  but for one preset added), or falls back to the custom sensor size where it does not know the
  preset. :data:`CAMERA_PRESETS` is that table.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from vebuild.errors import ProjectError

from .json_paths import json_path, parse_json_path

Point = tuple[float, float]
Segment = tuple[Point, Point]

#: fSpy's camera presets (``cameraPresets`` in fSpy's src/gui/solver/camera-presets.ts): id →
#: (sensor width, sensor height), millimetres.
CAMERA_PRESETS: dict[str, tuple[float, float]] = {
    "aps-c": (22.3, 14.9), "canon_1d": (27.9, 18.6), "canon_1ds": (36.0, 24.0), "canon_5d": (36.0, 24.0),
    "canon_7d": (22.3, 14.9), "canon_60d": (22.3, 14.9), "canon_500d": (22.3, 14.9), "canon_550d": (22.3, 14.9),
    "canon_600d": (22.3, 14.9), "canon_1100d": (22.2, 14.7), "canon_g7x_mk2": (13.2, 8.8),
    "35_mm_film": (36.0, 24.0), "micro_4_3rds": (17.3, 14.0), "nikon_d3s": (36.0, 23.9), "nikon_d90": (23.6, 15.8),
    "nikon_d300s": (23.6, 15.8), "nikon_d3100": (23.1, 15.4), "nikon_d5000": (23.6, 15.8),
    "nikon_d5100": (23.6, 15.6), "nikon_d7000": (23.6, 15.6), "red_epic": (30.0, 15.0), "red_epic_2k": (11.1, 6.24),
    "red_epic_3k": (16.65, 9.36), "red_epic_4k": (22.2, 12.6), "sony_a55": (23.4, 15.6), "iphone_6s": (4.8, 3.6),
}

#: The keys of a pair of control points saved as an object (``{ ...pair }`` of a list of two).
PAIR_KEYS = ("0", "1")


def kind(v: Any) -> str:
    """A value as a message shows it: short, whatever its type or size."""
    if v is None:
        return "null"
    if isinstance(v, bool):
        return f"{str(v).lower()} (a boolean)"
    if isinstance(v, int):
        digits = len(str(abs(v))) if abs(v) < 10 ** 30 else None
        return f"{v!r} (a number)" if digits is not None else "a whole number of more than 30 digits"
    if isinstance(v, float):
        return f"{v!r} (a number)"
    if isinstance(v, str):
        return f"{v!r} (text)" if len(v) < 60 else f"text of {len(v)} characters"
    if isinstance(v, list):
        return f"a list of {len(v)}"
    if isinstance(v, dict):
        return f"an object with {len(v)} key{'' if len(v) == 1 else 's'}" if len(v) != 0 else "an empty object"
    return type(v).__name__  # pragma: no cover - JSON has no other types


def as_float(v: Any) -> float | None:
    """A JSON number as a finite float; None for anything else (a boolean, text, a whole number too
    large for a float, a float that is not finite)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        f = float(v)
    except OverflowError:
        return None
    return f if math.isfinite(f) else None


class StateReader:
    """Values of the state JSON by their JSON paths (``$.a.b[1]``, ``$.a.horizon["0"]``)."""

    def __init__(self, path: Path, state: dict[str, Any]):
        self.path = path
        self.state = state

    def error(self, where: str, message: str) -> ProjectError:
        return ProjectError(self.path, where, message)

    def get(self, where: str, optional: bool = False) -> Any:
        """The value at ``where``; a missing one is an error (or None where ``optional``, as is a null)."""
        parts = parse_json_path(where)
        assert parts is not None, where
        node: Any = self.state
        done: list[str | int] = []
        for part in parts:
            here = json_path(done)
            if isinstance(part, int):
                if not isinstance(node, list) or part >= len(node):
                    raise self.error(here, f"expected a list of at least {part + 1}, found {kind(node)}")
                node = node[part]
            else:
                if not isinstance(node, dict):
                    raise self.error(here, f"expected an object, found {kind(node)}")
                if part not in node or (optional and node[part] is None):
                    if optional:
                        return None
                    raise self.error(json_path([*done, part]), "missing: the fSpy state has no such field (expected "
                                     "the state fSpy 1.x saves)")
                node = node[part]
            done.append(part)
        return node

    def obj(self, where: str) -> dict[str, Any]:
        v = self.get(where)
        if not isinstance(v, dict):
            raise self.error(where, f"expected an object, found {kind(v)}")
        return v

    def number(self, where: str, lo: float = -math.inf, hi: float = math.inf, what: str = "a number") -> float:
        v = self.get(where)
        f = as_float(v)
        if f is None or not lo <= f <= hi:
            raise self.error(where, f"expected {what}, found {kind(v)}")
        return f

    def choice(self, where: str, options: tuple[str, ...] | dict[str, Any], optional: bool = False) -> str | None:
        v = self.get(where, optional)
        if v is None and optional:
            return None
        if not isinstance(v, str) or v not in options:
            raise self.error(where, f"expected one of {', '.join(repr(o) for o in options)}, found {kind(v)}")
        return v

    def point(self, where: str, relative: bool = True) -> Point:
        v = self.get(where)
        if not isinstance(v, dict):
            raise self.error(where, f"expected a point {{\"x\": ..., \"y\": ...}}, found {kind(v)}")
        # Relative coordinates of a control point: 0 to 1 on the image; fSpy lets a point be dragged a
        # little past the edge, and vebuild's marks may lie within 4 image sizes of it (FORMAT.md).
        lo, hi, what = (-4.0, 5.0, "a relative image coordinate (0 to 1 across the image)") if relative else \
            (-1e9, 1e9, "a finite number")
        return (self.number(f"{where}.x", lo=lo, hi=hi, what=what), self.number(f"{where}.y", lo=lo, hi=hi, what=what))

    def pair(self, where: str) -> Segment:
        """Two control points: ``[{x, y}, {x, y}]``, or ``{"0": {x, y}, "1": {x, y}}`` as fSpy saves a
        pair it has changed (see the module's docstring)."""
        v = self.get(where)
        if isinstance(v, list) and len(v) == 2:
            return (self.point(f"{where}[0]"), self.point(f"{where}[1]"))
        if isinstance(v, dict) and sorted(v) == list(PAIR_KEYS):
            return (self.point(f'{where}["0"]'), self.point(f'{where}["1"]'))
        raise self.error(where, f"expected a pair of control points, [{{x, y}}, {{x, y}}] or {{\"0\": {{x, y}}, "
                         f"\"1\": {{x, y}}}}, found {kind(v)}" + (f" (keys {', '.join(map(repr, sorted(v)[:4]))})"
                                                                  if isinstance(v, dict) and v else ""))

    def segments(self, where: str) -> tuple[Segment, Segment]:
        v = self.get(f"{where}.lineSegments")
        if not isinstance(v, list) or len(v) != 2:
            raise self.error(f"{where}.lineSegments", f"expected two line segments, found {kind(v)}")
        return (self.pair(f"{where}.lineSegments[0]"), self.pair(f"{where}.lineSegments[1]"))

    def sensor(self) -> tuple[tuple[float, float], str]:
        """The sensor's size (mm) as fSpy's solver takes it, and where it came from: the preset's
        size where the project names one (its saved ``presetData``, or fSpy's table for a file
        from before fSpy saved it), else the custom size (fSpy's loader drops a preset it does
        not know, as here)."""
        base = "$.calibrationSettingsBase.cameraData"
        data = self.obj(base)
        preset_id = data.get("presetId")
        if preset_id is not None and not isinstance(preset_id, str):
            raise self.error(f"{base}.presetId", f"expected a camera preset's name or null, found {kind(preset_id)}")
        preset = data.get("presetData")
        if preset_id and preset is not None:
            if not isinstance(preset, dict):
                raise self.error(f"{base}.presetData", f"expected an object or null, found {kind(preset)}")
            w = self.number(f"{base}.presetData.sensorWidth", lo=1e-3, hi=1e4, what="a sensor width in millimetres")
            h = self.number(f"{base}.presetData.sensorHeight", lo=1e-3, hi=1e4, what="a sensor height in millimetres")
            return (w, h), f"the camera preset {preset_id!r}"
        if preset_id and preset_id in CAMERA_PRESETS:
            return CAMERA_PRESETS[preset_id], f"fSpy's camera preset {preset_id!r} (its sensor size from fSpy's table)"
        w = self.number(f"{base}.customSensorWidth", lo=1e-3, hi=1e4, what="a sensor width in millimetres")
        h = self.number(f"{base}.customSensorHeight", lo=1e-3, hi=1e4, what="a sensor height in millimetres")
        if preset_id:
            return (w, h), f"the custom sensor size (fSpy does not know the camera preset {preset_id!r} and uses it)"
        return (w, h), "the custom sensor size"
