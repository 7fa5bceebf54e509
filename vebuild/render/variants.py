"""The scene program's variants (``shaders/scene.frag``): one per lighting preset and mode.

On software OpenGL (llvmpipe) a fragment shader's cost is what it could do, not what it does:
the generic re-lit program, looping over ``n_lights`` lights whose types and shadow tiles are
uniforms, took 38 ms a frame at 1280×720 on the example room under one sun without shadows; the
same light with its type and tile compiled in took 14 ms. So the renderer compiles, per preset,
a variant whose light loop is unrolled for its lights (``N_LIGHTS``, ``LIGHT_TYPE_i``,
``LIGHT_TILE_i``), and per mode one whose texture and unobserved-marking choices are constants
(``TEXTURED``, ``UNOBSERVED_MODE``; ``UNOBSERVED_OFF`` drops the mask's sample altogether). Each
variant computes exactly what the generic program computes for those uniforms.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.lighting import MAX_LIGHTS, Lighting
from vebuild.render.shadows import MAX_TILES

LIGHT_TYPES = ("directional", "point", "spot")
#: The scene program's uniform arrays (lights and shadow tiles): a variant may keep only the
#: first elements of each (those its lights use), so the renderer writes only as many.
UNIFORM_ARRAYS = frozenset({"light_colour", "light_position", "light_direction", "light_cos_inner", "shadow_matrix",
                            "shadow_rect", "shadow_texel"})


def light_uniforms(lighting: Lighting, first: dict[int, int]) -> dict[str, NDArray[np.float32]]:
    """The light arrays of the scene program (``shaders/scene.frag``) for ``lighting``, each light's
    first shadow tile from ``first`` (-1: casts none)."""
    arr = {k: np.zeros((MAX_LIGHTS, 4), "f4") for k in ("light_colour", "light_position", "light_direction")}
    inner = np.zeros(MAX_LIGHTS, "f4")
    for i, li in enumerate(lighting.lights):
        arr["light_colour"][i] = [*li.colour, LIGHT_TYPES.index(li.type)]
        pos = li.position if li.position is not None else np.zeros(3)
        arr["light_position"][i] = [*pos, first.get(i, -1)]
        d = li.direction if li.direction is not None else np.array([0.0, 0.0, -1.0])
        arr["light_direction"][i] = [*d, math.cos(li.outer_cone)]
        inner[i] = math.cos(li.inner_cone)
    return {**arr, "light_cos_inner": inner}


def shadow_first_tiles(lighting: Lighting, shadows: bool) -> dict[int, int]:
    """Light index → its first tile in the shadow atlas, for the lights that cast shadows, in the
    order :meth:`vebuild.render.shadows.ShadowAtlas.update` lays them out (a point light takes six)."""
    first: dict[int, int] = {}
    if not (shadows and lighting.lit):
        return first
    n = 0
    for i, light in enumerate(lighting.lights):
        if light.shadows:
            first[i] = n
            n += 6 if light.type == "point" else 1
    return first


def scene_defines(lighting: Lighting, shadows: bool, textured: bool, unobserved_mode: int) -> dict[str, object]:
    """The ``#define``s of the scene program's variant for ``lighting`` (``shadows``: the
    renderer draws shadows), a textured scene or not, and ``unobserved_mode`` (0 off, 1 hatch,
    2 tint: the shader's ``unobserved_mode``)."""
    defines: dict[str, object] = {"LIT": int(lighting.lit), "MAX_LIGHTS": MAX_LIGHTS, "MAX_TILES": MAX_TILES,
                                  "TEXTURED": "true" if textured else "false",
                                  "UNOBSERVED_MODE": int(unobserved_mode) if textured else 0}
    if not textured or unobserved_mode == 0:
        defines["UNOBSERVED_OFF"] = 1
    if lighting.lit:
        first = shadow_first_tiles(lighting, shadows)
        defines["N_LIGHTS"] = len(lighting.lights)
        for i, light in enumerate(lighting.lights):
            defines[f"LIGHT_TYPE_{i}"] = LIGHT_TYPES.index(light.type)
            defines[f"LIGHT_TILE_{i}"] = first.get(i, -1)
    return defines


#: The scene's vertex layout: attribute names and float counts, in buffer order.
VERTEX_LAYOUT = (("in_position", 3), ("in_normal", 3), ("in_uv", 2), ("in_colour", 3), ("in_node", 1), ("in_face", 1))


def vertex_array(ctx: moderngl.Context, prog: moderngl.Program, vbo: moderngl.Buffer,
                 ibo: moderngl.Buffer) -> moderngl.VertexArray:
    """A vertex array over the scene's buffer for ``prog``, skipping attributes it does not use."""
    fmt = " ".join(f"{n}f" if name in prog else f"{4 * n}x" for name, n in VERTEX_LAYOUT)
    names = [name for name, _ in VERTEX_LAYOUT if name in prog]
    return ctx.vertex_array(prog, [(vbo, fmt, *names)], index_buffer=ibo)
