"""Lights and named lighting presets (FORMAT.md, ``lighting``), as plain data (pure numpy).

Units: a light's ``colour`` (linear RGB, default white) times its ``intensity`` (default 1) is the
irradiance it gives a surface facing it: for a directional light everywhere, for a point or spot
light at 1 m (it falls off with the inverse square of the distance). A surface under irradiance
E shows its texture colour times E, so an irradiance of 1 reproduces the texture as extracted.
``ambient`` (default 0.15 grey) is irradiance from every direction, unshadowed.

The built-in preset ``as-photographed`` is no lighting at all: the extracted textures shown as the
photos saw them (the renderer's unlit mode).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import ProjectError
from vebuild.project import AS_PHOTOGRAPHED, Project

Array = NDArray[np.float64]

DEFAULT_AMBIENT = (0.15, 0.15, 0.15)
#: The most lights one preset may have: the renderer's shaders hold this many (the project
#: schema's ``lights`` has the same ``maxItems``, so that a project with more is refused at load).
MAX_LIGHTS = 8
#: Cone of a spot light that gives none (degrees): outer edge, and where the fall-off starts.
DEFAULT_OUTER_CONE_DEG = 30.0
DEFAULT_INNER_CONE_FRACTION = 0.8


@dataclass(frozen=True)
class Light:
    """One light. ``direction`` is where the light travels (unit); ``position`` in metres."""

    type: str  # "directional", "point" or "spot"
    colour: Array  # linear RGB × intensity
    direction: Array | None = None
    position: Array | None = None
    inner_cone: float = 0.0  # radians, spot lights
    outer_cone: float = 0.0
    shadows: bool = True
    name: str = ""


@dataclass(frozen=True)
class Lighting:
    """A lighting preset: ambient irradiance and lights. ``lit`` False is the unlit mode."""

    name: str
    lit: bool
    ambient: Array = field(default_factory=lambda: np.array(DEFAULT_AMBIENT))
    lights: tuple[Light, ...] = ()
    description: str = ""

    @property
    def shadow_casters(self) -> tuple[Light, ...]:
        return tuple(light for light in self.lights if light.shadows)


AS_PHOTOGRAPHED_LIGHTING = Lighting(AS_PHOTOGRAPHED, lit=False, ambient=np.ones(3), lights=(),
                                    description="the extracted textures as the photos saw them, unlit")


def light_from_record(rec: dict[str, Any]) -> Light:
    """A :class:`Light` from its (validated) record."""
    colour = np.asarray(rec.get("colour", (1.0, 1.0, 1.0)), float) * float(rec.get("intensity", 1.0))
    d = rec.get("direction")
    direction = None if d is None else np.asarray(d, float) / np.linalg.norm(d)
    position = None if rec.get("position") is None else np.asarray(rec["position"], float)
    outer = np.radians(rec.get("outer_cone_deg", DEFAULT_OUTER_CONE_DEG))
    inner = np.radians(rec["inner_cone_deg"]) if "inner_cone_deg" in rec else DEFAULT_INNER_CONE_FRACTION * outer
    return Light(rec["type"], colour, direction, position, float(min(inner, outer)), float(outer),
                 bool(rec.get("shadows", True)), rec.get("name", ""))


def preset_from_record(rec: dict[str, Any]) -> Lighting:
    return Lighting(rec["name"], True, np.asarray(rec.get("ambient", DEFAULT_AMBIENT), float),
                    tuple(light_from_record(r) for r in rec.get("lights", [])), rec.get("description", ""))


def preset_names(project: Project) -> list[str]:
    """The built-in preset and the project's, in order."""
    return [AS_PHOTOGRAPHED] + [p["name"] for p in (project.data.get("lighting") or {}).get("presets", [])]


def find_preset(project: Project, name: str | None) -> Lighting:
    """The preset called ``name`` (None: as photographed); an error listing them if there is none."""
    if name is None or name == AS_PHOTOGRAPHED:
        return AS_PHOTOGRAPHED_LIGHTING
    for rec in (project.data.get("lighting") or {}).get("presets", []):
        if rec["name"] == name:
            return preset_from_record(rec)
    known = ", ".join(repr(n) for n in preset_names(project))
    raise ProjectError(project.path, "$.lighting.presets", f"no lighting preset is called {name!r}; the presets "
                       f"are: {known}")
