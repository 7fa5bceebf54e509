"""Shadow maps of the renderer (paper §5, re-lighting): one tile of a shared depth atlas per
directional or spot light (orthographic fitted to the scene, or perspective over its cone), six
per point light (one per cube face, in the order ``shaders/scene.frag``'s ``cube_face`` uses).
:func:`light_tiles` gives each tile's world → clip matrix (pure math); :class:`ShadowAtlas` owns the
depth texture, draws the tiles into it and gives the uniforms the scene shader reads."""

from __future__ import annotations

import math
from collections.abc import Sequence

import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.camera import gl_orthographic, gl_projection, intrinsic_matrix, look_rotation, view_matrix
from vebuild.gl.context import max_texture_size
from vebuild.gl.shaders import uniform
from vebuild.lighting import Light

Array = NDArray[np.float64]

#: Shadow tiles at most: a directional or spot light takes one, a point light six.
MAX_TILES = 24
#: A point light's tiles look along these directions, in the order scene.frag's cube_face uses.
CUBE_DIRECTIONS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
#: Pixels kept free around a point light's 90° cube face inside its tile, for the shadow filter.
CUBE_MARGIN_PX = 2.0


def light_tiles(light: Light, size: int, bounds: tuple[Array, Array]) -> list[tuple[Array, tuple[float, float]]]:
    """(world → clip matrix, shadow texel size (at 1 m, perspective?)) of each of a light's tiles,
    for a scene within ``bounds`` (its lower and upper corners) and tiles ``size`` pixels square."""
    lo, hi = bounds
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    if light.type == "directional":
        assert light.direction is not None  # a directional light has one (lighting.Light)
        R = look_rotation(light.direction)
        xc = corners @ R.T
        pad = 0.01 * max(1e-3, float(np.ptp(xc, axis=0).max())) + 1e-3
        a, b = xc.min(axis=0) - pad, xc.max(axis=0) + pad
        return [(gl_orthographic(R, a, b), (float((b - a)[:2].max()) / size, 0.0))]
    position = light.position
    assert position is not None  # point and spot lights have one (lighting.Light)
    far = float(np.linalg.norm(corners - position, axis=1).max()) * 1.05 + 0.1
    near = min(0.02, 0.5 * far)
    dirs: list[Array]
    if light.type == "spot":
        assert light.direction is not None
        half = min(light.outer_cone + math.radians(2.0), math.radians(89.0))
        f = 0.5 * size / math.tan(half)
        dirs = [light.direction]
    else:
        f = 0.5 * size - CUBE_MARGIN_PX
        dirs = list(CUBE_DIRECTIONS)
    K = intrinsic_matrix(f, size / 2, size / 2)
    P = gl_projection(K, size, size, near, far)
    return [(P @ view_matrix(look_rotation(d), position), (1.0 / f, 1.0)) for d in dirs]


class ShadowAtlas:
    """The shadow maps' depth atlas of one GL context: drawn by :meth:`update`, released with
    :meth:`release`."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.texture: moderngl.Texture | None = None
        self._fbo: moderngl.Framebuffer | None = None

    def update(self, lights: Sequence[Light], size: int, bounds: tuple[Array, Array], program: moderngl.Program,
               vao: moderngl.VertexArray, n_vertices: int) -> dict[str, object]:
        """Draw the tiles of every light of ``lights`` that casts shadows (each ``size`` pixels
        square, fewer where the atlas would pass the context's texture limit) with the depth-only
        ``program`` over ``vao``; returns the state the scene shader's uniforms take: ``first``
        (light index → its first tile), ``n`` (tiles) and, with tiles, ``matrices``, ``rects``
        (each tile's place in the atlas) and ``texels``."""
        tiles: list[tuple[Array, tuple[float, float]]] = []
        first: dict[int, int] = {}
        for i, light in enumerate(lights):
            if light.shadows:
                first[i] = len(tiles)
                tiles += light_tiles(light, size, bounds)
        state: dict[str, object] = {"first": first, "n": len(tiles)}
        if not tiles:
            return state
        cols = math.ceil(math.sqrt(len(tiles)))
        rows = math.ceil(len(tiles) / cols)
        limit = max_texture_size(self.ctx)
        size = min(size, limit // cols, limit // rows)
        W, H = cols * size, rows * size
        if self.texture is None or self.texture.size != (W, H):
            self.release()
            depth = self.ctx.depth_texture((W, H))
            depth.compare_func = "<="
            depth.filter = (moderngl.LINEAR, moderngl.LINEAR)
            depth.repeat_x = depth.repeat_y = False
            self.texture, self._fbo = depth, self.ctx.framebuffer(depth_attachment=depth)
        fbo = self._fbo
        assert fbo is not None
        fbo.use()
        fbo.viewport = (0, 0, W, H)
        fbo.clear(depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        rects = []
        for k, (M, _) in enumerate(tiles):
            x, y = (k % cols) * size, (k // cols) * size
            fbo.viewport = (x, y, size, size)
            uniform(program, "light_matrix").write(M.T.astype("f4").tobytes())
            vao.render(moderngl.TRIANGLES, vertices=n_vertices)
            rects.append((x / W, y / H, size / W, size / H))
        self.ctx.disable(moderngl.DEPTH_TEST)
        texel = np.zeros((MAX_TILES, 2), "f4")
        texel[: len(tiles)] = [t for _, t in tiles]
        mats = np.zeros((MAX_TILES, 4, 4), "f4")
        mats[: len(tiles)] = [M.T for M, _ in tiles]
        rect = np.zeros((MAX_TILES, 4), "f4")
        rect[: len(tiles)] = rects
        state.update(matrices=mats, rects=rect, texels=texel)
        return state

    def release(self) -> None:
        if self._fbo is not None:
            self._fbo.release()
        if self.texture is not None:
            self.texture.release()
        self.texture = self._fbo = None
