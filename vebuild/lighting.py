"""Lights and named lighting presets (FORMAT.md, ``lighting``), as plain data (layer 1, pure numpy).

They are decoded from the project by :mod:`vebuild.project.decode` (``find_preset``) and drawn by
:mod:`vebuild.render.renderer`.

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

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: The name of the built-in preset: no lighting, the textures as the photos saw them.
AS_PHOTOGRAPHED = "as-photographed"
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
